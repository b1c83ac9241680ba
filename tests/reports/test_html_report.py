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
    from gyrocal.metrology.gum import round_to_uncertainty
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
    identifiable = results["allan"]["identifiable"]
    for name, entry in results["allan"]["uncertainty"].items():
        if identifiable.get(name) is False:    # issue 28: said so, never "0 ± U"
            continue
        shown = "{} ± {}".format(*round_to_uncertainty(entry["value"], entry["U"]))
        assert f"<td>{shown} " in html, name
    assert not all(identifiable.values())     # this record cannot tell every term from zero
    unidentified = sum(1 for name in results["allan"]["uncertainty"]
                       if identifiable.get(name) is False)
    assert len(re.findall(r"</td><td>not identifiable from this record \(95 % upper bound \S+ ",
                          html)) == unidentified


def _visible_text(html: str) -> str:
    return re.sub(r"<[^>]+>", " ", re.sub(r'src="data:[^"]+"', "", html))


def test_rows_read_as_words_with_units(evil_run):
    """No raw results keys as labels; every residual, value and limit carries its unit."""
    from gyrocal.models.noise_terms import FIT_KEYS

    html = (evil_run / "report" / "report.html").read_text()
    text = _visible_text(html)
    for label in ("Q — quantization noise", "N — angle random walk", "B — bias instability",
                  "K — rate random walk", "R — rate ramp"):
        assert label in text, label
    for key in FIT_KEYS:
        assert key not in text, key
    assert "Bias over temperature (deg/h)" in text
    # the Allan terms' 68 % intervals carry the term's unit
    assert re.search(r"\S+ … \S+ deg/√h", text)


def test_compensation_residuals_carry_their_units(evil_run):
    """Two temperatures give no residuals; with three (tables made by the report's own
    builder) every residual is printed with the table's unit."""
    from gyrocal.reports.build import _comp_tables
    from gyrocal.reports.html_report import render_html
    from gyrocal.reports.sections.compensation import CompensationResults

    results = json.loads((evil_run / "report" / "results.json").read_text())
    notes: list[str] = []
    bias = ((-10.0, 1.2), (25.0, 2.0), (60.0, 3.5))
    sf = ((-10.0, 0.99990), (25.0, 1.0), (60.0, 1.00012))
    results["compensation"] = CompensationResults(bias, sf, {
        "bias_dph": _comp_tables(list(bias), "bias", notes),
        "sf": _comp_tables(list(sf), "sf", notes)}).to_json()
    assert not notes
    text = _visible_text(render_html(results))
    assert re.search(r"in-sample RMS residual \S+ deg/h, leave-one-out RMS \S+ deg/h, "
                     r"max \S+ deg/h", text), "bias compensation residuals without units"
    assert re.search(r"in-sample RMS residual \S+ deg/s per deg/s, leave-one-out RMS \S+ "
                     r"deg/s per deg/s", text)
    assert "Scale factor over temperature (deg/s per deg/s)" in text
    assert "Value ± U (95 %, deg/h)" in text


def test_acceptance_values_and_limits_carry_their_unit(evil_run):
    results = json.loads((evil_run / "report" / "results.json").read_text())
    text = " ".join(_visible_text((evil_run / "report" / "report.html").read_text()).split())
    for entry in results["acceptance"]:
        assert entry["unit"] == "%"
        assert re.search(rf"{re.escape(entry['metric'])} \S+ ± \S+ % max {entry['limit']:g} %",
                         text), entry["name"]


def test_plots_are_sized_to_read(evil_run):
    html = (evil_run / "report" / "report.html").read_text()
    for image in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html):
        png = base64.b64decode(image)
        width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
        assert width >= 800 and height >= 450, (width, height)
