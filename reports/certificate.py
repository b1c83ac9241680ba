"""The calibration certificate (ISO/IEC 17025 §7.8) as a PDF, from a run's results.json.

Rendered with reportlab (a PDF library of long standing, pure wheels from
PyPI: no system packages, so `make` on a fresh machine needs nothing more).
Content follows §7.8.2/7.8.4: title and unique number, lab name and address
(station ``site``), customer, unit identity, dates of calibration and issue,
method (procedure, its SHA-256, software), conditions (chamber setpoints and
the temperatures measured), results with units, expanded uncertainty and k
(values rounded to the digits their U supports: U to two significant digits,
GUM 7.2.6), traceability (reference instruments, serials, calibration due),
the decision rule and conformity statement per limit, and the approval (name,
role, date) with the run's cryptographic signature where it was signed.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from reportlab.lib import colors
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import getSampleStyleSheet
from reportlab.lib.units import mm
from reportlab.pdfgen.canvas import Canvas
from reportlab.platypus import Paragraph, SimpleDocTemplate, Spacer, Table, TableStyle

from gyrocal.metrology.gum import round_to_uncertainty
from gyrocal.metrology.metrics import CERTIFIED_METRICS
from gyrocal.record.atomic import write_atomic
from gyrocal.record.journal import Journal, JournalEvent, sha256_file
from gyrocal.record.run_folder import JOURNAL, RunFolder, RunFolderError
from gyrocal.record.signing import Signer
from gyrocal.record.strays import set_aside
from gyrocal.reports.build import RESULTS_FILE
from gyrocal.reports.labels import acceptance_unit

CERTIFICATE_FILE = "report/certificate.pdf"
#: The title of a simulated run's certificate (and the watermark on each of its pages).
SIMULATED_TITLE = "SIMULATED — not a calibration"


@dataclass(frozen=True)
class Approval:
    """Who authorises the certificate (ISO/IEC 17025 §7.8.2.1 o)."""

    name: str
    role: str
    date: dt.date


def result_rows(results: dict[str, Any]) -> list[list[str]]:
    """Quantity, value, U, k, unit: one row per certified number."""
    rows = [["Quantity", "Value", "U (95 %)", "k", "Unit"]]
    for entry in results.get("scale_factor") or []:
        value, big_u = round_to_uncertainty(entry["sf"], entry.get("U"))
        rows.append([f"Scale factor at {entry['temp_c']:g} °C", value, big_u,
                     _k(entry.get("k")), "output/(deg/s)"])
    for entry in results.get("bias") or []:
        value, big_u = round_to_uncertainty(entry["bias_dph"], entry.get("U"))
        rows.append([f"Bias at {entry['temp_c']:g} °C (Earth rate removed)", value, big_u,
                     _k(entry.get("k")), "deg/h"])
    table = results.get("uncertainty") or {}
    for metric in CERTIFIED_METRICS:     # the catalogue's certified single figures, in row order
        item = table.get(metric.key)
        if item is None or metric.certified is None:
            continue
        value, big_u = round_to_uncertainty(item["value"], item.get("U"))
        rows.append([metric.certified.label, value, big_u, _k(item.get("k")),
                     metric.certified.unit])
    return rows


def _k(k: float | None) -> str:
    return "—" if k is None else f"{k:.2f}"


def _kv(rows: list[tuple[str, str]], style) -> Table:
    table = Table([[Paragraph(f"<b>{k}</b>", style), Paragraph(_esc(v), style)] for k, v in rows],
                  colWidths=[45 * mm, 125 * mm])
    table.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP")]))
    return table


def _esc(text: Any) -> str:
    return (str(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;"))


def _grid(rows: list[list[str]], widths: list[float], style) -> Table:
    table = Table([[Paragraph(_esc(c), style) for c in row] for row in rows],
                  colWidths=[w * mm for w in widths], repeatRows=1)
    table.setStyle(TableStyle([
        ("GRID", (0, 0), (-1, -1), 0.4, colors.grey),
        ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#e8e8e8")),
        ("VALIGN", (0, 0), (-1, -1), "TOP")]))
    return table


def _numbered_canvas(number: str) -> type[Canvas]:
    """A canvas that writes "Certificate N — page x of y" at the foot of every page.

    ISO/IEC 17025 §7.8.2.1 c): each page identifies the certificate and says it is part of a
    whole of known length. y is known only once the story is laid out, so pages are kept
    and stamped when the document is saved.
    """
    class NumberedCanvas(Canvas):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._pages: list[dict[str, Any]] = []

        def showPage(self) -> None:  # noqa: N802 - reportlab's name
            self._pages.append(dict(self.__dict__))
            self._startPage()

        def save(self) -> None:
            total = len(self._pages)
            for index, page in enumerate(self._pages, start=1):
                self.__dict__.update(page)
                self.setFont("Helvetica", 8)
                self.drawString(18 * mm, 9 * mm, f"Calibration certificate {number}")
                self.drawRightString(A4[0] - 18 * mm, 9 * mm, f"page {index} of {total}")
                super().showPage()
            super().save()

    return NumberedCanvas


def write_certificate(results: dict[str, Any], path: Path, number: str, customer: str,
                      approval: Approval) -> Path:
    """Renders the certificate PDF to ``path``; returns it."""
    styles = getSampleStyleSheet()
    body = styles["BodyText"]
    body.fontSize, body.leading = 8.5, 10.5
    simulated = is_simulated(results)
    story = [*_front_matter(results, number, customer, approval, styles),
             *_measurement_sections(results, styles["Heading2"], body),
             *_closing_sections(results, approval, styles["Heading2"], body)]
    title = f"{SIMULATED_TITLE}: {number}" if simulated else f"Calibration certificate {number}"

    def render(target: Path) -> None:
        doc = SimpleDocTemplate(str(target), pagesize=A4, title=title,
                                leftMargin=18 * mm, rightMargin=18 * mm, topMargin=15 * mm,
                                bottomMargin=15 * mm)
        decorate = _watermark if simulated else _no_decoration
        doc.build(story, onFirstPage=decorate, onLaterPages=decorate,
                  canvasmaker=_numbered_canvas(number))

    # Atomic: a kill mid-render leaves a temporary file (set aside later), never half a PDF.
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, render, mode=0o644)
    return path


def _front_matter(results: dict[str, Any], number: str, customer: str, approval: Approval,
                  styles: Any) -> list[Any]:
    """Title (SIMULATED for a dry run), number, who, what, when and by which method."""
    body = styles["BodyText"]
    run = results.get("run") or {}
    site = (results.get("station") or {}).get("site") or {}
    uut = results.get("unit_under_test") or {}
    procedure = results.get("procedure") or {}
    inputs = results.get("inputs") or {}
    heading = ([Paragraph(SIMULATED_TITLE, styles["Title"]),
                Paragraph("Calibration certificate layout, from a dry run against simulated "
                          "instruments: no instrument was calibrated and no value below "
                          "describes a real unit.", body)]
               if is_simulated(results) else [Paragraph("Calibration Certificate", styles["Title"])])
    return [
        *heading,
        Paragraph(f"Certificate number <b>{_esc(number)}</b>; every page carries it and its "
                  "page number; this certificate may not be reproduced other than in full.",
                  body),
        Spacer(1, 4 * mm),
        _kv([("Laboratory", f"{site.get('name') or '—'}, {site.get('address') or 'address not declared'}"),
             ("Customer", customer),
             ("Item calibrated", f"{uut.get('model')} serial {uut.get('serial')} "
                                 f"{_unit_says(results)}(output units {uut.get('output_units')})"),
             ("Input chain", _input_chain(results)),
             ("Date of calibration", calibration_dates(run)),
             ("Date of issue", approval.date.isoformat()),
             ("Method", f"gyrocal procedure {procedure.get('name')!s} "
                        f"(file {procedure.get('file')}, SHA-256 "
                        f"{(inputs.get('procedure') or {}).get('sha256', '—')}); software "
                        f"{_software(run.get('software'))}; run {run.get('run_id')}"),
             ], body),
    ]


def _unit_says(results: dict[str, Any]) -> str:
    """The serial the unit itself reported (a STIM300's I<CR>), when it did."""
    reported = ((results.get("instruments") or {}).get("gyro") or {}).get("reported_serial")
    return f"(the unit reports serial {reported}) " if reported else ""


def _measurement_sections(results: dict[str, Any], h2: Any, body: Any) -> list[Any]:
    """Conditions, results with U and how U was stated, and traceability."""
    return [
        Paragraph("Conditions during the calibration", h2),
        _grid([["Setpoint (°C)", "Chamber measured (°C)", "Sensor measured (°C)"]] +
              [[f"{e['temp_c']:g}", _num(e.get("chamber_temp_c"), 2),
                _num(e.get("sensor_temp_c"), 2)] for e in results.get("scale_factor") or []],
              [40, 50, 50], body),
        Paragraph("Results", h2),
        _grid(result_rows(results), [70, 30, 25, 12, 33], body),
        Paragraph("The expanded uncertainty U = k·u is stated at a coverage probability of about "
                  "95 %. k is the t-factor for the effective degrees of freedom (Welch–"
                  "Satterthwaite, JCGM 100 G.4); where a rectangular input (a reference "
                  "instrument's accuracy) is in the budget, the 95 % point of the budget "
                  "sampled per JCGM 101; for the nonlinearity figures, the 95 % point of the "
                  "noise that the dwells cannot tell from nonlinearity. Coverage measured over "
                  "400 simulated calibrations: docs/uncertainty-coverage.md. The budgets are "
                  "in results.json.", body),
        Paragraph("Traceability", h2),
        _grid([["Reference", "Instrument", "Serial (declared / reported)",
                 "Its calibration certificate", "Calibration due"]] +
              [[role, f"{i.get('make')} {i.get('model')}",
                f"{i.get('serial')} / {i.get('reported_serial') or '—'}", _traceable_to(i),
                f"{i.get('calibration_due') or '—'}"
                + (" OVERDUE" if i.get("calibration_overdue") else "")]
               for role, i in sorted((results.get("instruments") or {}).items())
               if role != "gyro"], [20, 40, 40, 46, 28], body),
    ]


def _closing_sections(results: dict[str, Any], approval: Approval, h2: Any,
                      body: Any) -> list[Any]:
    """The decision rule and conformity per limit, the overall statement, the approval."""
    verdict = results.get("verdict") or {}
    return [
        Paragraph("Decision rule and conformity", h2),
        _grid([["Limit", "Value ± U", "Limit", "Rule", "Guard band", "Decision"]] +
              [_conformity_row(a) for a in results.get("acceptance") or []],
              [42, 32, 25, 18, 25, 28], body),
        Paragraph(f"Overall statement of conformity: <b>{_esc(verdict.get('overall'))}</b>. "
                  "simple rule: the value alone is compared with the limit; guarded rule "
                  "(ILAC-G8): conformity is stated only when value ± U lies within the limit. "
                  + _esc(" ".join(verdict.get("blocked_because") or [])), body),
        Paragraph("Approval", h2),
        _kv([("Authorised by", f"{approval.name}, {approval.role}"),
             ("Date", approval.date.isoformat()),
             ("Run signature", _signature(results)),
             ("Signature", "\n\n______________________________")], body),
    ]


def is_simulated(results: dict[str, Any]) -> bool:
    """A dry run (simulated instruments), by the mode run_started fixed."""
    run = results.get("run") or {}
    return bool(run.get("simulated")) or run.get("mode") == "sim"


def _watermark(canvas: Any, doc: Any) -> None:
    """Across every page of a simulated run's certificate, so no page can pass for a real one."""
    canvas.saveState()
    canvas.setFillColor(colors.Color(0.85, 0.2, 0.2, alpha=0.25))
    canvas.setFont("Helvetica-Bold", 64)
    width, height = A4
    canvas.translate(width / 2, height / 2)
    canvas.rotate(45)
    canvas.drawCentredString(0, 0, "SIMULATED")
    canvas.setFont("Helvetica-Bold", 20)
    canvas.drawCentredString(0, -40, "not a calibration")
    canvas.restoreState()


def _no_decoration(canvas: Any, doc: Any) -> None:
    return None


def _input_chain(results: dict) -> str:
    """How the unit's output was read: the gyro interface's driver and what it said it is."""
    gyro = (results.get("instruments") or {}).get("gyro") or {}
    return f"{gyro.get('driver') or '—'}: {gyro.get('description') or 'not identified'}"


def calibration_dates(run: dict[str, Any]) -> str:
    """From the first step to the last (not from connecting the instruments to writing the
    report); a dry run says that its procedure ran on simulated time, and how long it is."""
    start = run.get("steps_started_at") or run.get("started_at")
    end = run.get("steps_done_at") or run.get("ended_at")
    span = f"{_utc(start)} to {_utc(end)}" if end else f"from {_utc(start)} (not finished)"
    if run.get("mode") != "sim":
        return span
    length = run.get("procedure_s")
    procedure = f"{_hours_minutes(length)} of procedure " if isinstance(length, (int, float)) \
        else "the procedure "
    pace = "as fast as the machine allows" if run.get("speed") in (None, "max") \
        else f"at {run.get('speed')}× real time"
    return (f"{str(start)[:10]}: a dry run on simulated instruments, {procedure}on simulated "
            f"time, {pace} ({span}); no physical unit was calibrated")


def _utc(stamp: Any) -> str:
    """``2026-11-24T09:05:27+0000`` -> ``2026-11-24 09:05:27 UTC``."""
    text = str(stamp or "—")
    return text[:19].replace("T", " ") + " UTC" if text.endswith("+0000") else text


def _hours_minutes(seconds: float) -> str:
    minutes = int(round(seconds / 60.0))
    return f"{minutes // 60} h {minutes % 60:02d} min" if minutes >= 60 else f"{minutes} min"


def _traceable_to(instrument: dict[str, Any]) -> str:
    """The reference instrument's own certificate and issuer, as the station declares them."""
    number, issuer = instrument.get("calibration_certificate"), instrument.get("calibrated_by")
    if not number and not issuer:
        return "not declared in the station"
    return " by ".join(str(x) for x in (number or "(number not declared)", issuer) if x)


def _conformity_row(entry: dict[str, Any]) -> list[str]:
    """One limit: value ± U, the limit and the guard band, each with its unit."""
    unit = acceptance_unit(entry)
    suffix = f" {unit}" if unit else ""
    value = (" ± ".join(round_to_uncertainty(entry.get("value"), entry.get("U")))
             if entry.get("U") else _num(entry.get("value"), 6))
    band = _num(entry.get("guard_band"), 3)
    return [entry["name"], value + suffix, f"{entry['kind']} {entry['limit']:g}{suffix}",
            entry.get("decision_rule", "simple"), band + (suffix if band != "—" else ""),
            entry.get("decision") or ("PASS" if entry.get("pass") else "FAIL")]


def _num(value: float | None, digits: int) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    text = f"{value:.{digits}g}" if digits > 3 else f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def _software(software: Any) -> str:
    if isinstance(software, dict):
        return " ".join(str(v) for v in software.values())
    return str(software)


def _signature(results: dict[str, Any]) -> str:
    sig = results.get("signature") or {}
    if not sig.get("signed"):
        return "the run was not signed (no station signing key)"
    return f"Ed25519, key {sig.get('key_fingerprint')}: {str(sig.get('signature'))[:48]}…"


def certify_run(run_dir: Path, *, customer: str, approval: Approval, number: str | None = None,
                out: Path | None = None, signer: Signer | None = None
                ) -> tuple[Path, str, str | None]:
    """Write the certificate of the run in ``run_dir`` from its report/results.json.

    Returns (PDF path, certificate number, overall verdict). The number defaults to
    ``GC-<run id>``; the PDF is readable by the group (a QA office reads it). The
    certificate joins the run's history: a ``certificate_written`` event records its
    number, its SHA-256 and the results it was made from, sealed with ``signer`` like
    a report rebuild, so ``verify`` accounts for it. The caller holds the folder's lock.
    """
    source = run_dir / RESULTS_FILE
    if not source.is_file():
        raise RunFolderError(f"{source}: missing; run `gyrocal report {run_dir}` first")
    try:
        results = json.loads(source.read_text())
    except json.JSONDecodeError as exc:
        raise RunFolderError(f"{source}: not valid JSON: {exc}") from None
    folder = RunFolder.open(run_dir)
    run_id = (results.get("run") or {}).get("run_id") or run_dir.name
    number = number or f"GC-{run_id}"
    path = out if out is not None else run_dir / CERTIFICATE_FILE
    with Journal(folder.path / JOURNAL) as journal:
        set_aside(folder.path, journal, folder.journal_events(), folder.read_manifest())
        write_certificate(results, path, number, customer, approval)
        inside = path.resolve().is_relative_to(folder.path.resolve())
        journal.append(JournalEvent.CERTIFICATE_WRITTEN, number=number,
                       path=str(path.resolve().relative_to(folder.path.resolve()) if inside
                                else path.resolve()),
                       in_run_folder=inside, sha256=sha256_file(path),
                       results_sha256=sha256_file(source), simulated=is_simulated(results),
                       customer=customer, approved_by=approval.name)
        if signer is not None:
            signer.seal(journal, str(run_id), reason="certificate written")
    return path, number, (results.get("verdict") or {}).get("overall")
