"""The README's main command, end to end: the smoke dry run, its audit, and the discrepancy act."""

import hashlib
import json
from pathlib import Path

import pytest

from gyrocal.cli import main
from gyrocal.models.gyro_model import load_model

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_demo_runs_the_smoke_procedure_and_names_the_hidden_effect(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "every hash matches" in out
    # The demo ends with the audit of both runs — after certifying the first (issue 28: the
    # certificate is part of the audited history): OK, the certificate's hash, the seals.
    tail = out.strip().splitlines()[-5:]
    assert tail[0].startswith(str(tmp_path / "smoke")) and ": OK" in tail[0]
    results = json.loads((tmp_path / "smoke" / "report" / "results.json").read_text())
    certificate = tmp_path / "smoke" / "report" / "certificate.pdf"     # issue 11
    digest = hashlib.sha256(certificate.read_bytes()).hexdigest()
    assert tail[1] == (f"  certificate GC-{results['run']['run_id']}: report/certificate.pdf "
                       f"SHA-256 {digest}")
    assert "authentic: 2 seal(s) verified with the given key" in tail[2]   # run, certificate
    assert tail[3].startswith(str(tmp_path / "hidden-effect")) and ": OK" in tail[3]
    assert "authentic: 1 seal(s) verified" in tail[4]
    assert out.index("certificate GC-") < out.index("== audit:")
    assert all(item["pass"] for item in results["acceptance"])
    assert certificate.read_bytes()[:5] == b"%PDF-"
    assert f"certificate GC-{results['run']['run_id']}: {certificate}" in out

    # Act 2: the station's gyro carries sf_asymmetry (40 ppm); the nominal model lacks it.
    truth = load_model(REPO / "gyro-models" / "fog-hidden-asymmetry.yaml").effect("sf_asymmetry")["ppm"]
    document = json.loads((tmp_path / "discrepancy" / "discrepancy.json").read_text())
    assert [f["name"] for f in document["found"]] == ["sf_asymmetry"]
    assert document["found"][0]["parameters"]["ppm"] == pytest.approx(truth, rel=0.1)
    assert document["unexplained"] is False
    gap = document["gap"]
    assert gap["before"] > 20 * gap["noise_floor"]
    assert gap["after"] < 3 * gap["noise_floor"]
    updated = load_model(tmp_path / "discrepancy" / "updated-model.yaml")
    assert updated.has_effect("sf_asymmetry")
    assert "named: sf_asymmetry" in out


def test_real_instruments_refuse_a_fast_clock(tmp_path, capsys):
    station = (REPO / "stations" / "sim.yaml").read_text()
    station = station.replace("address: sim  ", "address: socket://127.0.0.1:9  ", 1)
    station = station.replace("  address: sim\n", "  address: TCPIP0::127.0.0.1::9::SOCKET\n", 1)
    station = station.replace("port: sim", "port: /dev/ttyUSB9")
    station = station.replace("../gyro-models/", str(REPO / "gyro-models") + "/")
    (tmp_path / "lab.yaml").write_text(station)
    code = main(["run", str(REPO / "procedures" / "smoke.yaml"), "--station",
                 str(tmp_path / "lab.yaml"), "--speed", "max", "--out", str(tmp_path / "r")])
    assert code == 2
    assert "only --sim runs can change the clock" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()
