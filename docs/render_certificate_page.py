"""Renders page 1 of a certificate PDF to PNG (docs/certificate-page.png), with pdfium.

    .venv/bin/gyrocal run procedures/smoke.yaml --sim --out /tmp/smoke
    .venv/bin/gyrocal certificate /tmp/smoke --customer "ACME Navigation" --approved-by "A. Auditor" --role "Quality manager"
    .venv/bin/python docs/render_certificate_page.py /tmp/smoke/report/certificate.pdf docs/certificate-page.png
"""

from __future__ import annotations

import sys

import pypdfium2 as pdfium


def main(pdf_path: str, png_path: str) -> None:
    page = pdfium.PdfDocument(pdf_path)[0]
    page.render(scale=1.3).to_pil().save(png_path)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
