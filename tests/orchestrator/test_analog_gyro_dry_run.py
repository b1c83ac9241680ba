"""The KVG25 with analog output, through the simulated DMM, end to end (procedures/kvg25-analog-dmm.yaml).

The simulated 34465A samples the shared gyro model's volts on its sample
timer; the run measures the scale factor in V per deg/s. The model's scale
factor at the LS-line temperature — 0.025 V/(deg/s) at 25 °C with its
20 ppm/°C tempco (gyro-models/kvg25-analog.yaml) — must lie inside the
reported expanded uncertainty, and the report must say the chain was analog.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def certificate_text(run: Path) -> str:
    """The certificate `gyrocal certificate` writes for ``run``, as text."""
    from pypdf import PdfReader

    proc = subprocess.run([sys.executable, "-m", "gyrocal", "certificate", str(run),
                           "--customer", "ACME", "--approved-by", "A. Auditor"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    pages = PdfReader(run / "report" / "certificate.pdf").pages
    return " ".join(" ".join(page.extract_text() for page in pages).split())


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_dry_run_recovers_the_models_volts_per_dps_within_the_reported_uncertainty(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "gyrocal", "run",
                           str(ROOT / "procedures" / "kvg25-analog-dmm.yaml"), "--sim",
                           "--out", str(out)], capture_output=True, text=True, timeout=280)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    results = json.loads((out / "report" / "results.json").read_text())
    fit = results["scale_factor_ls"]
    truth = 0.025 * (1 + 20e-6 * (fit["temp_c"] - 25.0))
    assert abs(fit["sf"] - truth) <= fit["U"], (fit["sf"], truth, fit["U"])
    assert fit["U"] < 1e-5 * 0.025 * 100          # a meaningful bound: under 0.1 % of the SF
    gyro = results["instruments"]["gyro"]
    assert gyro["driver"] == "keysight_34465a"
    assert gyro["description"].startswith("analog input chain: DC volts through")
    html = next((out / "report").glob("*.html")).read_text()
    assert "analog input chain" in html
    reads = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()
             if '"event":"supply_read"' in line]
    assert reads and all(r["ok"] and r["voltage_v"] == 12.0 for r in reads)
    text = certificate_text(out)
    assert "Input chain keysight_34465a: analog input chain: DC volts through" in text


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_dithered_rlg_through_the_counter_recovers_its_scale_factor_in_whole_pulses(tmp_path):
    """procedures/rlg-pulse-counter.yaml: SF = 1 + 5 ppm + 0.1 ppm/°C·(T − 25) (the model's
    sf_error and tempco) inside U; every logged readout is a whole number of 2-arcsec pulses."""
    import pyarrow.parquet as pq

    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "gyrocal", "run",
                           str(ROOT / "procedures" / "rlg-pulse-counter.yaml"), "--sim",
                           "--out", str(out)], capture_output=True, text=True, timeout=280)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    results = json.loads((out / "report" / "results.json").read_text())
    fit = results["scale_factor_ls"]
    truth = 1.0 + 5e-6 + 0.1e-6 * (fit["temp_c"] - 25.0)
    assert abs(fit["sf"] - truth) <= fit["U"], (fit["sf"], truth, fit["U"])
    assert results["instruments"]["gyro"]["description"].startswith("pulse input chain")
    assert "Input chain keysight_53230a: pulse input chain: timed totalize" in certificate_text(out)
    pulses_per_dps = 1.0 / ((2.0 / 3600.0) * 200.0)        # one readout of 5 ms
    for chunk in sorted((out / "samples" / "T01.static").glob("*.parquet")):
        pulses = pq.read_table(chunk, columns=["gyro"]).column("gyro").to_numpy() * pulses_per_dps
        assert np.allclose(pulses, np.round(pulses), atol=1e-6)
        assert len(np.unique(np.round(pulses))) >= 2       # the count steps by one pulse
