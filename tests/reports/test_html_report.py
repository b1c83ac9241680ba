"""report.html: self-contained, readable, and every user-supplied string escaped."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import pytest

from gyrocal.cli import main

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(120)
EVIL = "<script>alert(1)</script>"


@pytest.fixture(scope="module")
def evil_run(tmp_path_factory) -> Path:
    """The smoke procedure with markup in its name, serial and operator."""
    tmp = tmp_path_factory.mktemp("evil")
    text = (ROOT / "procedures" / "smoke.yaml").read_text()
    text = text.replace("name: Smoke test (two temperatures near ambient)", f"name: 'Smoke {EVIL}'")
    text = text.replace("serial: SIM-0001", f"serial: 'SN{EVIL}'")
    text = text.replace("../stations/sim.yaml", str(ROOT / "stations" / "sim.yaml"))
    procedure = tmp / "evil.yaml"
    procedure.write_text(text)
    run_dir = tmp / "run"
    assert main(["run", str(procedure), "--sim", "--seed", "5", "--out", str(run_dir),
                 "--operator", f"op{EVIL}"]) == 0
    return run_dir


def test_user_strings_are_escaped(evil_run):
    html = (evil_run / "report" / "report.html").read_text()
    assert "<script" not in html.lower()
    assert html.count("&lt;script&gt;alert(1)&lt;/script&gt;") >= 3  # name, serial, operator
    results = json.loads((evil_run / "report" / "results.json").read_text())
    assert results["unit_under_test"]["serial"] == f"SN{EVIL}"  # JSON keeps the raw value


def test_page_is_self_contained_with_real_plots(evil_run):
    html = (evil_run / "report" / "report.html").read_text()
    assert not re.search(r"""(src|href)=["'](?!data:)""", html)  # nothing loaded from outside
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)
    assert len(images) == 5  # SF vs rate, residuals, SF vs T, bias vs T, Allan
    for image in images:
        assert base64.b64decode(image)[:8] == b"\x89PNG\r\n\x1a\n"


def test_page_carries_what_qa_signs(evil_run):
    html = (evil_run / "report" / "report.html").read_text()
    results = json.loads((evil_run / "report" / "results.json").read_text())
    for text in ("12-3456", "2027-06-30", "SIM0001", "Sim lab", "PASS",
                 results["inputs"]["procedure"]["sha256"], results["run"]["plan_sha256"],
                 results["journal"]["samples_sha256"], results["run"]["run_id"]):
        assert text in html, text
    assert "OVERDUE" not in html  # the sim station's instruments are in calibration


def test_overdue_calibration_and_failed_limit_are_flagged(evil_run):
    from gyrocal.reports.html_report import render_html

    results = json.loads((evil_run / "report" / "results.json").read_text())
    results["instruments"]["table"]["calibration_due"] = "2001-01-01"
    results["instruments"]["table"]["calibration_overdue"] = True
    results["acceptance"][0].update({"pass": False, "decision": "FAIL"})
    results["journal"]["events"].append({"seq": 99, "event": "retry", "instrument": "chamber",
                                         "detail": f"timeout {EVIL}"})
    html = render_html(results)
    assert "OVERDUE" in html and "FAIL" in html
    assert "timeout &lt;script&gt;" in html and "<script" not in html.lower()


def test_values_carry_their_expanded_uncertainty_and_the_decision(smoke_run):
    """Issue 11: SF, bias and acceptance values are printed as value ± U with the digits U
    supports (GUM 7.2.6), with k and the decision rule; a CONDITIONAL decision is shown."""
    from gyrocal.reports.gum import round_to_uncertainty
    from gyrocal.reports.html_report import render_html

    results = json.loads((smoke_run / "report" / "results.json").read_text())
    results["acceptance"][0].update({"decision": "CONDITIONAL", "decision_rule": "guarded"})
    html = render_html(results)
    for entry in results["scale_factor"]:
        value, expanded = round_to_uncertainty(entry["sf"], entry["U"])
        assert f"<td>{value} ± {expanded}</td>" in html
    for point in results["bias"]:
        value, expanded = round_to_uncertainty(point["bias_dph"], point["U"])
        assert f"<td>{value} ± {expanded}</td>" in html
    assert "guarded" in html and ">CONDITIONAL</span>" in html
    ls = results["scale_factor_ls"]
    assert "SF {} ± {},".format(*round_to_uncertainty(ls["sf"], ls["U"])) in html
    for name, entry in results["allan"]["uncertainty"].items():
        shown = "{} ± {}".format(*round_to_uncertainty(entry["value"], entry["U"]))
        assert f"<td>{shown} " in html, name
