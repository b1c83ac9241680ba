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
