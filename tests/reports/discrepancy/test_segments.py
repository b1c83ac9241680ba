"""Segments: a table slew never swallows the constant-rate segment beside it."""

import numpy as np

from gyrocal.analysis.discrepancy.segments import derive_segments


def _quiet_seconds(segments, fs: float) -> float:
    return sum((s.stop - s.start) / fs for s in segments.quiet_slices(fs))


def test_one_hour_static_then_a_ten_sample_slew_keeps_its_quiet_hour():
    fs = 200.0
    n_static = int(3600 * fs)
    slew = np.linspace(0.0, 10.0, 12)[1:-1]            # 10 samples accelerating
    dwell = np.full(int(120 * fs), 10.0)
    rate = np.concatenate([np.zeros(n_static), slew, dwell])
    t = np.arange(rate.size) / fs
    segments = derive_segments(t, rate, np.full(rate.size, 25.0))
    # before the fix: the slew was merged into the static, which then counted as "table moving"
    assert _quiet_seconds(segments, fs) >= 3600 - 10 * 2.0 + 120 - 2.0 - 1.0
    slew_segments = [name for name in segments.names if "table moving" in name]
    assert len(slew_segments) == 1
    assert not any(q for q, name in zip(segments.quiet, segments.names, strict=True)
                   if "table moving" in name)


def test_the_workflow_runs_its_linear_algebra_on_one_blas_thread(monkeypatch) -> None:
    """Issue 15: threadpoolctl, not hand-written ctypes, limits BLAS inside the analysis."""
    from threadpoolctl import threadpool_info

    from gyrocal.analysis.discrepancy import workflow

    seen = []
    monkeypatch.setattr(workflow, "_analyse", lambda *a, **k: seen.append(
        [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]))
    workflow.analyse(None, None)   # the passes are replaced: only the limit is looked at
    assert seen and seen[0] and all(n == 1 for n in seen[0])
