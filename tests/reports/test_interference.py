"""Table-induced interference against a truth typed here: the vendor's 12.48 Hz family."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gyrocal.analysis.environment.interference import compare, drift_dph, sine_amplitude
from gyrocal.cli import main

FS_HZ = 250.0
N = 150_000                         # 600 s
# (frequency Hz, amplitude deg/h 0-to-peak): the vendor notes' family, amplitudes chosen here
LINES = ((12.48, 3.0), (24.96, 1.5), (37.44, 0.8))


def _records(seed: int = 4):
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS_HZ
    off = 1.0 + rng.standard_normal(N) * 2.0
    # drive powered: the white noise 6× (so the drift of 1-s means is 6×) plus the lines
    powered = 1.0 + rng.standard_normal(N) * 12.0
    for f, a in LINES:
        powered += a * np.sin(2 * np.pi * f * t + 0.7)
    return powered, off


def test_drift_ratio_and_lines_of_the_vendor_case():
    powered, off = _records()
    result = compare(powered, off, FS_HZ)
    # 1-s means of white noise: 12/sqrt(250) and 2/sqrt(250) deg/h; the lines average out
    assert result.drift_off_dph == pytest.approx(2.0 / np.sqrt(250), rel=0.1)
    assert result.drift_ratio == pytest.approx(6.0, rel=0.12)
    assert [round(line.frequency_hz, 2) for line in result.lines] == [12.48, 24.96, 37.44]
    for line, (f, a) in zip(result.lines, LINES, strict=True):
        assert line.frequency_hz == pytest.approx(f, abs=2e-3)
        assert line.amplitude_dph == pytest.approx(a, rel=0.06)
        assert line.amplitude_off_dph < 0.1          # absent with the drive off
    assert [line.harmonic for line in result.lines] == [1, 2, 3]


def test_no_lines_where_there_are_none():
    rng = np.random.default_rng(1)
    assert compare(rng.standard_normal(N), rng.standard_normal(N), FS_HZ).lines == ()


def test_sine_amplitude_and_drift_by_hand():
    t = np.arange(1000) / 100.0
    assert sine_amplitude(2.5 * np.cos(2 * np.pi * 7.0 * t) + 4.0, 100.0, 7.0) == pytest.approx(2.5)
    # means of 1 s over [0,0,...,1,1,...] alternating by second: std of (0, 1, 0, 1)
    y = np.repeat([0.0, 1.0, 0.0, 1.0], 100)
    assert drift_dph(y, 100.0, 1.0) == pytest.approx(np.std([0, 1, 0, 1], ddof=1))
    with pytest.raises(ValueError, match="at least 3"):
        drift_dph(y, 100.0, 2.0)


def test_cli_reads_two_logs(tmp_path, capsys):
    powered, off = _records(seed=9)
    for name, dph in (("on.csv", powered), ("off.csv", off)):
        t = np.arange(N) / FS_HZ
        np.savetxt(tmp_path / name, np.column_stack([t, dph / 3600.0]), delimiter=",",
                   header="t_s,gyro", comments="", fmt="%.12g")
    out = tmp_path / "i.json"
    assert main(["analyze", "interference", str(tmp_path / "on.csv"), str(tmp_path / "off.csv"),
                 "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert [round(x["frequency_hz"], 2) for x in doc["lines"]] == [12.48, 24.96, 37.44]
    text = capsys.readouterr().out
    assert "drift ratio" in text and "12.48" in text
