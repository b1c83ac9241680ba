"""The report page and the certificate as a reader sees them (issue 11): the HTML rendered by
a real headless Chromium, the PDF rasterised by pdfium - not only their source text.

With ``GYROCAL_SCREENSHOTS=docs`` the test also writes docs/report-page.png and
docs/certificate-page.png, the images the README shows.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pypdfium2 as pdfium
from selenium.webdriver.common.by import By

from gyrocal.cli import main
from tests.support.browser import headless_chromium


def test_report_page_renders_values_with_u_and_the_decisions(smoke_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    browser = headless_chromium()
    try:
        browser.get((run / "report" / "report.html").resolve().as_uri())
        headings = [h.text for h in browser.find_elements(By.TAG_NAME, "h2")]
        assert {"Acceptance", "Scale factor", "Bias"} <= set(headings)
        tables = browser.find_elements(By.TAG_NAME, "table")
        acceptance = next(t for t in tables if "Decision rule" in t.text)
        assert "Value ± U (95 %)" in acceptance.text and "PASS" in acceptance.text
        sf_table = next(t for t in tables if "SF (LS) ± U" in t.text)
        rows = sf_table.find_elements(By.TAG_NAME, "tr")[1:]
        assert rows and all(" ± " in r.find_elements(By.TAG_NAME, "td")[2].text for r in rows)
        width = browser.execute_script("return document.documentElement.scrollWidth")
        assert width <= 1400, f"the page is {width} px wide: a table overflows the window"
        if os.environ.get("GYROCAL_SCREENSHOTS"):
            browser.save_screenshot(str(Path(os.environ["GYROCAL_SCREENSHOTS"]) / "report-page.png"))
    finally:
        browser.quit()


def test_certificate_page_is_drawn_not_blank(smoke_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    assert main(["certificate", str(run), "--customer", "ACME Navigation GmbH",
                 "--approved-by", "A. Auditor", "--role", "Quality manager"]) == 0
    document = pdfium.PdfDocument(run / "report" / "certificate.pdf")
    page = document[0]
    image = np.asarray(page.render(scale=1.0).to_pil().convert("L"), dtype=float)
    ink = (image < 128).mean()
    assert 0.01 < ink < 0.5, f"{ink:.3%} of page 1 is dark: blank or a black page"
    text = page.get_textpage().get_text_range()
    assert "Calibration certificate" in text or "CALIBRATION CERTIFICATE" in text.upper()
    if os.environ.get("GYROCAL_SCREENSHOTS"):
        page.render(scale=1.3).to_pil().save(
            str(Path(os.environ["GYROCAL_SCREENSHOTS"]) / "certificate-page.png"))
