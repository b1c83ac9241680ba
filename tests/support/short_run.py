"""The shortest run that still has every record kind: one temperature, a static, a ± pair.

Used where a test repeats a whole run per record boundary (kill -9, signals),
so each repetition costs a fraction of a second of simulated time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

SHORT_PLAN = ("T01.ramp", "T01.soak", "T01.static", "T01.sf.+20dps", "T01.sf.-20dps")


def short_procedure(h: Any, folder: Path) -> Path:
    """The engine tests' small procedure (``h.write_procedure``) cut to its first temperature."""
    path = h.write_procedure(folder)
    text = path.read_text()
    cut = text.index("  - setpoint_c: 27.0")
    path.write_text(text[:cut])
    return path


def without_report_figures(monkeypatch: Any) -> None:
    """The report pages this process builds get no figures (every figure section empty).

    For the sweeps that resume one run per boundary (kill -9, signals), and fixtures that
    make many runs only to read their records (the runs database's ten): there each
    run or resume builds the report, and its five Matplotlib figures are ~60 % of a
    short run's CPU time, while what those tests assert (exit codes, the signed history,
    each step once with its data, results.json) never reads them. The report is still built, written atomically,
    journaled and hashed as in any run; the figures themselves are asserted where they
    are the point (tests/reports/) and are drawn by every other dry run of the suite.
    Processes the sweep forks (the killed runs) skip them too: ``ForkServer.run(...,
    figures=False)``.
    """
    from gyrocal.reports import html_report, plots

    empty = plots.all_plots({})
    assert empty and all(figure is None for figure in empty.values())
    monkeypatch.setattr(html_report, "all_plots", lambda results: dict(empty))
