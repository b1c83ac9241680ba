"""The calibration certificate PDF, read back with an independent reader (pypdf)."""

from __future__ import annotations

import json
import shutil
import stat

import numpy as np
import pytest
from pypdf import PdfReader

from gyrocal.cli import main
from gyrocal.reports.certificate import round_to_uncertainty


@pytest.mark.parametrize(("value", "expanded", "expected"), [
    (100.02147, 0.00035, ("100.02147", "0.00035")),    # GUM 7.2.6's example (u_c = 0.35 mg)
    (1.2345678, 0.0123, ("1.235", "0.012")),
    (0.99875, 1.1301e-05, ("0.998750", "0.000011")),
    (12345.6, 230.0, ("12350", "230")),
])
def test_values_get_the_digits_their_uncertainty_supports(value, expanded, expected):
    assert round_to_uncertainty(value, expanded) == expected


def test_certificate_pdf_carries_number_customer_values_and_u(smoke_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    code = main(["certificate", str(run), "--customer", "ACME Navigation GmbH",
                 "--number", "GC-2026-0042", "--approved-by", "A. Auditor",
                 "--role", "Quality manager"])
    assert code == 0
    pdf = run / "report" / "certificate.pdf"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert stat.S_IMODE(pdf.stat().st_mode) & stat.S_IRGRP       # readable by the group
    text = " ".join(page.extract_text() for page in PdfReader(pdf).pages)
    text = " ".join(text.split())
    results = json.loads((run / "report" / "results.json").read_text())
    for expected in ("GC-2026-0042", "ACME Navigation GmbH", "A. Auditor", "Quality manager",
                     "SIM-0001", "Sim lab", "SIM0001", "2027-03-31", "guarded" if any(
                         a.get("decision_rule") == "guarded" for a in results["acceptance"])
                     else "simple", results["verdict"]["overall"]):
        assert expected in text, expected
    for entry in results["scale_factor"]:
        value, expanded = round_to_uncertainty(entry["sf"], entry["U"])
        assert f"{value} {expanded} {entry['k']:.2f}" in text
        # the printed value is the measured one to within the printed resolution
        assert float(value) == pytest.approx(entry["sf"], abs=float(expanded))


def test_certificate_without_a_report_is_bad_input(tmp_path, capsys):
    (tmp_path / "manifest.json").write_text("{}")
    assert main(["certificate", str(tmp_path)]) == 2
    assert "results.json" in capsys.readouterr().err


def test_every_page_names_the_certificate_and_counts_the_pages(smoke_run, tmp_path):
    """ISO/IEC 17025 §7.8.2.1: each page identifies the certificate and its place in it."""
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["certificate", str(run), "--number", "GC-2026-0099"]) == 0
    pages = PdfReader(run / "report" / "certificate.pdf").pages
    assert len(pages) >= 2
    for index, page in enumerate(pages, start=1):
        text = " ".join(page.extract_text().split())
        assert "Calibration certificate GC-2026-0099" in text, index
        assert f"page {index} of {len(pages)}" in text, index


def test_conformity_values_limits_and_guard_bands_carry_units(smoke_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["certificate", str(run)]) == 0
    text = " ".join(" ".join(p.extract_text() for p in PdfReader(
        run / "report" / "certificate.pdf").pages).split())
    results = json.loads((run / "report" / "results.json").read_text())
    assert results["acceptance"]
    for entry in results["acceptance"]:
        value, expanded = round_to_uncertainty(entry["value"], entry["U"])
        assert f"{value} ± {expanded} %" in text, entry["name"]
        assert f"{entry['kind']} {entry['limit']:g} %" in text, entry["name"]


def test_traceability_names_each_reference_instruments_own_certificate(smoke_run, tmp_path):
    """The chain: our result ← the table and chamber ← their certificates (station identity)."""
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["certificate", str(run)]) == 0
    text = " ".join(" ".join(p.extract_text() for p in PdfReader(
        run / "report" / "certificate.pdf").pages).split())
    results = json.loads((run / "report" / "results.json").read_text())
    for role in ("chamber", "table"):
        instrument = results["instruments"][role]
        assert instrument["calibration_certificate"] and instrument["calibrated_by"], role
        assert (f"{instrument['calibration_certificate']} by {instrument['calibrated_by']}"
                in text), role
    html = (run / "report" / "report.html").read_text()
    assert "SIM-RT-2026-004 by Sim calibration services" in html


def test_calibration_dates_come_from_the_steps_and_a_dry_run_says_so(smoke_run, tmp_path):
    """A dry run's wall span is seconds; the certificate says the procedure ran on simulated
    time, how long it is (the plan's ETA), and the span of its steps."""
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["certificate", str(run)]) == 0
    text = " ".join(" ".join(p.extract_text() for p in PdfReader(
        run / "report" / "certificate.pdf").pages).split())
    results = json.loads((run / "report" / "results.json").read_text())
    manifest = json.loads((run / "manifest.json").read_text())
    journal = [json.loads(line) for line in (run / "journal.jsonl").read_text().splitlines()]
    first_step = next(e for e in journal if e["event"] == "step_started")
    assert results["run"]["steps_started_at"][:19] == __import__("time").strftime(
        "%Y-%m-%dT%H:%M:%S", __import__("time").gmtime(first_step["wall_time"]))
    minutes = round(manifest["eta_s"] / 60)
    assert f"a dry run on simulated instruments, {minutes} min of procedure on simulated time" \
        in text
    assert "as fast as the machine allows" in text and "no physical unit was calibrated" in text
    assert results["run"]["steps_started_at"][:19].replace("T", " ") + " UTC" in text


def test_a_certified_run_still_verifies_and_verify_names_the_certificate(smoke_run, tmp_path,
                                                                         capsys):
    """issue 28: the certificate joins the history; verify passes after it and gives its hash."""
    import hashlib

    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["verify", str(run)]) == 0
    assert main(["certificate", str(run), "--number", "GC-TEST-1"]) == 0
    events = [json.loads(line) for line in (run / "journal.jsonl").read_text().splitlines()]
    written = events[-1]
    digest = hashlib.sha256((run / "report" / "certificate.pdf").read_bytes()).hexdigest()
    assert written["event"] == "certificate_written" and written["sha256"] == digest
    assert written["number"] == "GC-TEST-1" and written["simulated"] is True
    capsys.readouterr()
    assert main(["verify", str(run)]) == 0
    assert f"certificate GC-TEST-1: report/certificate.pdf SHA-256 {digest}" in \
        capsys.readouterr().out
    (run / "report" / "certificate.pdf").write_bytes(b"%PDF-1.4 forged\n")
    assert main(["verify", str(run)]) == 1
    assert "certificate.pdf" in capsys.readouterr().err


def test_a_simulated_certificate_cannot_pass_for_a_real_one(smoke_run, tmp_path):
    """Title and a watermark on every page say SIMULATED — not a calibration (issue 28)."""
    import pypdfium2 as pdfium

    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["certificate", str(run)]) == 0
    pdf = run / "report" / "certificate.pdf"
    reader = PdfReader(pdf)
    assert reader.metadata.title.startswith("SIMULATED — not a calibration")
    pages = [" ".join(page.extract_text().split()) for page in reader.pages]
    assert len(pages) >= 2
    assert "SIMULATED — not a calibration" in pages[0]
    for number, text in enumerate(pages, start=1):       # the watermark, page by page
        assert "SIMULATED" in text and "not a calibration" in text, number
    # and it is drawn, not only text: the watermark's colour is on every rendered page
    document = pdfium.PdfDocument(pdf)
    for index in range(len(document)):
        image = np.asarray(document[index].render(scale=0.5).to_pil().convert("RGB"), dtype=float)
        reddish = (image[..., 0] - image[..., 2] > 25) & (image[..., 0] > 200)
        assert reddish.mean() > 0.002, f"page {index + 1}: no watermark drawn"
