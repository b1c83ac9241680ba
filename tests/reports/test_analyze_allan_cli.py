"""gyrocal analyze allan: JSON keys of interfaces.md, units/scale handling, bad input → exit 2."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gyrocal.cli import main

pytestmark = pytest.mark.timeout(60)
FS_HZ = 100.0
N_TRUE = 0.05  # deg/√h
KEYS = {"tau_s", "adev_dph", "adev_lo_dph", "adev_hi_dph", "fit"}
FIT_KEYS = {"Q_arcsec", "N_deg_per_rth", "B_dph", "K_dph_per_rth", "R_dph_per_h", "markov"}


def _write_csv(path: Path, gyro: np.ndarray, t_s: np.ndarray | None = None) -> Path:
    t = np.arange(gyro.size) / FS_HZ if t_s is None else t_s
    zeros = np.zeros(gyro.size)
    table = np.column_stack([t, zeros, zeros + 25.0, gyro])
    np.savetxt(path, table, delimiter=",", header="t_s,table_rate_dps,chamber_temp_c,gyro",
               comments="", fmt="%.10g")
    return path


@pytest.fixture(scope="module")
def white_dph() -> np.ndarray:
    """White rate noise with ARW N_TRUE, in deg/h (per-sample std N·60·√fs)."""
    rng = np.random.default_rng(11)
    return 3.0 + rng.standard_normal(200_000) * N_TRUE * 60.0 * math.sqrt(FS_HZ)


def _run(tmp_path: Path, log: Path, *extra: str) -> dict:
    out = tmp_path / "allan.json"
    assert main(["analyze", "allan", str(log), "--json", str(out), *extra]) == 0
    return json.loads(out.read_text())


def test_json_has_exactly_the_spec_keys_and_recovers_n(tmp_path, white_dph):
    log = _write_csv(tmp_path / "log.csv", white_dph / 3600.0)  # deg/s, the default units
    result = _run(tmp_path, log)
    assert set(result) == KEYS
    assert set(result["fit"]) == FIT_KEYS
    n = len(result["tau_s"])
    assert n > 20 and all(len(result[k]) == n for k in KEYS - {"fit"})
    lo, mid, hi = (np.array(result[k]) for k in ("adev_lo_dph", "adev_dph", "adev_hi_dph"))
    assert np.all(lo <= mid) and np.all(mid <= hi)
    # white rate noise: σ(τ) = N·60/√τ deg/h, and the fit gives N back
    tau = np.array(result["tau_s"])
    assert mid[0] == pytest.approx(N_TRUE * 60.0 / math.sqrt(tau[0]), rel=0.02)
    assert result["fit"]["N_deg_per_rth"] == pytest.approx(N_TRUE, rel=0.05)


def test_units_and_scale_factor_are_applied(tmp_path, white_dph):
    reference = _run(tmp_path, _write_csv(tmp_path / "dps.csv", white_dph / 3600.0))
    sf = 2.5  # output units per input unit: the log holds 2.5 × rad/s
    rad_per_s = white_dph / 3600.0 * math.pi / 180.0 * sf
    result = _run(tmp_path, _write_csv(tmp_path / "rad.csv", rad_per_s),
                  "--units", "rad/s", "--scale-factor", str(sf))
    assert result["adev_dph"] == pytest.approx(reference["adev_dph"], rel=1e-6)
    dph = _run(tmp_path, _write_csv(tmp_path / "dph.csv", white_dph), "--units", "deg/h")
    assert dph["adev_dph"] == pytest.approx(reference["adev_dph"], rel=1e-6)


def test_non_numeric_row_names_line_and_column(tmp_path, capsys):
    log = _write_csv(tmp_path / "bad.csv", np.ones(50))
    lines = log.read_text().splitlines()
    lines[7] = lines[7].rsplit(",", 1)[0] + ",oops"
    log.write_text("\n".join(lines) + "\n")
    assert main(["analyze", "allan", str(log)]) == 2
    err = capsys.readouterr().err
    assert "line 8" in err and "gyro" in err and "Traceback" not in err


def test_unknown_column_and_time_gap_are_bad_input(tmp_path, capsys):
    log = _write_csv(tmp_path / "ok.csv", np.ones(100))
    assert main(["analyze", "allan", str(log), "--column", "gyro_x"]) == 2
    assert "gyro_x" in capsys.readouterr().err
    t = np.arange(100) / FS_HZ
    t[60:] += 1.0
    gap = _write_csv(tmp_path / "gap.csv", np.ones(100), t_s=t)
    assert main(["analyze", "allan", str(gap)]) == 2
    err = capsys.readouterr().err
    assert "row 61" in err and "t_s" in err and "gap" in err


def test_run_folder_uses_its_longest_hold(tmp_path, smoke_run, capsys):
    from gyrocal.record.run_folder import RunFolder

    run_dir = smoke_run
    capsys.readouterr()
    result = _run(tmp_path, run_dir)
    out = capsys.readouterr().out
    assert "step T0" in out and ".static" in out
    assert set(result) == KEYS
    assert RunFolder.open(run_dir).read_manifest()["state"] == "done"
    assert result["fit"]["N_deg_per_rth"] == pytest.approx(0.01, rel=0.1)  # nominal-fog ARW
