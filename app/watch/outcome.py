"""How a finished run ended, for the live page: its verdict and where its report is.

"done" says the steps ran; QA needs the verdict (PASS, FAIL, CONDITIONAL, BLOCKED,
INVALID) and the report. Both are read from the run folder (``report/results.json``,
written by the report), never from a controller's memory.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

from gyrocal.record.run_folder import MANIFEST

RESULTS = "report/results.json"
REPORT = "report/report.html"


@dataclass(frozen=True)
class Outcome:
    verdict: str | None          # None until the report is written
    failed: list[str]            # acceptance limits that did not pass
    reasons: list[str]           # why INVALID / BLOCKED / CONDITIONAL
    report: str | None           # the report's path in the run folder, once written
    speed: str | None            # "max" (simulated time), or the real-time factor

    def to_json(self) -> dict:
        return asdict(self)


def read_outcome(run_dir: Path) -> Outcome:
    run_dir = Path(run_dir)
    speed = _manifest_speed(run_dir)
    try:
        results = json.loads((run_dir / RESULTS).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return Outcome(None, [], [], None, speed)
    verdict = results.get("verdict") if isinstance(results, dict) else None
    if not isinstance(verdict, dict):
        return Outcome(None, [], [], None, speed)
    failed = [str(a.get("name")) for a in results.get("acceptance") or []
              if isinstance(a, dict) and a.get("pass") is False]
    reasons = [str(r) for key in ("invalid_because", "blocked_because", "conditional")
               for r in verdict.get(key) or []]
    report = REPORT if (run_dir / REPORT).is_file() else None
    return Outcome(str(verdict.get("overall")), failed, reasons, report, speed)


def _manifest_speed(run_dir: Path) -> str | None:
    try:
        speed = json.loads((run_dir / MANIFEST).read_text(encoding="utf-8")).get("speed")
    except (OSError, ValueError, AttributeError):
        return None
    return None if speed is None else str(speed)
