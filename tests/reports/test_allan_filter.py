"""`analyze allan --filter`: the filters against truths derived by hand from their equations.

For white rate noise of per-sample variance s², the steady-state Kalman filter
of analysis/allan/filtering.py is the first-order smoother x_k = (1 − g)·x_k−1 +
g·y_k with g = 1/(τ_f·fs); its output has variance s²·g/(2 − g) and lag-one
correlation 1 − g, so its Allan variance at τ = 1/fs is s²·g²/(2 − g), while
at τ ≫ τ_f it is the input's (the filter keeps what changes slowly).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gyrocal.analysis.allan import filtering as af
from gyrocal.cli import main

pytestmark = pytest.mark.timeout(120)
FS_HZ = 100.0
SIGMA_DPH = 30.0            # per-sample white noise: N = 30 / (60·√100) = 0.05 deg/√h


def _write_csv(path: Path, gyro_dps: np.ndarray) -> Path:
    t = np.arange(gyro_dps.size) / FS_HZ
    np.savetxt(path, np.column_stack([t, gyro_dps]), delimiter=",", header="t_s,gyro",
               comments="", fmt="%.12g")
    return path


@pytest.fixture(scope="module")
def white_log(tmp_path_factory) -> Path:
    rng = np.random.default_rng(26)
    dph = 3.0 + rng.standard_normal(300_000) * SIGMA_DPH
    return _write_csv(tmp_path_factory.mktemp("f") / "white.csv", dph / 3600.0)


def _adev_at(doc: dict, tau_s: float) -> float:
    tau = np.array(doc["tau_s"])
    return float(np.interp(np.log(tau_s), np.log(tau), np.array(doc["adev_dph"])))


def test_kalman_reduces_short_term_allan_deviation_as_its_equation_says(tmp_path, white_log, capsys):
    out = tmp_path / "a.json"
    assert main(["analyze", "allan", str(white_log), "--filter", "kalman", "--filter-tau-s", "0.5",
                 "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    f = doc["filter"]
    g = 1.0 / (0.5 * FS_HZ)                                   # 0.02
    assert f["steady_gain"] == pytest.approx(g)
    assert f["r_dph2"] == pytest.approx(SIGMA_DPH**2, rel=0.01)   # var(dy)/2 of white noise
    assert f["dropped_samples"] == 250                        # 5 τ_f
    # at τ = 1/fs: s·g/√(2 − g) = 30·0.02/√1.98 = 0.4264 deg/h (before: 30 deg/h)
    assert doc["adev_dph"][0] == pytest.approx(SIGMA_DPH, rel=0.01)
    assert f["after"]["adev_dph"][0] == pytest.approx(SIGMA_DPH * g / math.sqrt(2 - g), rel=0.02)
    # at τ = 100 s (200 τ_f) the filtered record's Allan deviation is the input's
    assert _adev_at(f["after"], 100.0) == pytest.approx(_adev_at(doc, 100.0), rel=0.05)
    # the terms before and after with the reduction the printout states
    for key, pct in f["reduction_pct"].items():
        before, after = doc["fit"][key], f["after"]["fit"][key]
        assert pct is None if before == 0 else pct == pytest.approx((before - after) / before * 100)
    assert f["reduction_pct"]["Q_arcsec"] > 50.0          # the τ⁻¹ (quantization-like) part goes
    text = capsys.readouterr().out
    assert "kalman filter (state: rate (deg/h) as a random walk" in text
    assert "from time constant 0.5 s" in text and "reduced by" in text
    assert "left as they are" in text


def _run_filter(kind: af.FilterKind, y: np.ndarray, r: float) -> np.ndarray:
    tuning = af.tune(kind, r, FS_HZ, 0.5, forgetting=0.999)
    blocks = [y[i:i + 4096] for i in range(0, y.size, 4096)]
    return np.concatenate(list(af.filtered_blocks(lambda: iter(blocks), tuning)()))


def test_adaptive_kalman_lowers_its_gain_when_the_noise_grows():
    # The noise doubles halfway. The Kalman filter keeps g = 0.02; Sage-Husa re-estimates r
    # (4×), so its steady gain becomes about √(q/4r) = g/2 and its output variance
    # s²·g/(2 − g) halves: the adaptive/plain variance ratio in the second half is ~0.5.
    rng = np.random.default_rng(5)
    y = np.concatenate([rng.standard_normal(100_000) * 10.0, rng.standard_normal(100_000) * 20.0])
    plain = _run_filter(af.FilterKind.KALMAN, y, 100.0)
    adaptive = _run_filter(af.FilterKind.ADAPTIVE_KALMAN, y, 100.0)
    second = slice(-60_000, None)
    ratio = np.var(adaptive[second]) / np.var(plain[second])
    assert 0.4 < ratio < 0.62, ratio
    # in the first half the noise is what r was set from: both filters agree
    first = slice(20_000, 90_000)
    assert np.var(adaptive[first]) / np.var(plain[first]) == pytest.approx(1.0, abs=0.12)


def test_filtering_is_the_same_whatever_the_block_size():
    rng = np.random.default_rng(8)
    y = rng.standard_normal(20_000)
    tuning = af.tune(af.FilterKind.ADAPTIVE_KALMAN, 1.0, FS_HZ, 0.3)
    one = np.concatenate(list(af.filtered_blocks(lambda: iter([y]), tuning)()))
    many = np.concatenate(list(af.filtered_blocks(lambda: iter(np.array_split(y, 37)), tuning)()))
    np.testing.assert_array_equal(one, many)


@pytest.mark.parametrize(("extra", "message"), [
    (["--filter-tau-s", "0.001"], "shorter than one sample"),
    (["--filter-tau-s", "-1"], "time constant must be > 0"),
    (["--forgetting", "1.5"], "forgetting factor"),
])
def test_bad_filter_settings_are_bad_input(white_log, capsys, extra, message):
    assert main(["analyze", "allan", str(white_log), "--filter", "adaptive-kalman", *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "white.csv" in err and "Traceback" not in err
