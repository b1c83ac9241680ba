"""``gyrocal discrepancy --model M --measured LOG_OR_RUN_DIR --out DIR [--seed N]``.

Reads and checks both inputs before any analysis (a bad model key or a bad
log row is exit 2 with a message naming it), runs the workflow and writes
the three files of the interfaces contract: discrepancy.json,
updated-model.yaml (loadable by ``load_model``) and discrepancy.html.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

from gyrocal.analysis.discrepancy.workflow import analyse
from gyrocal.analysis.measured_log import read_measured_log
from gyrocal.models.gyro_model import dump_model, load_model
from gyrocal.reports.discrepancy_story import write_html


def _finite(value):
    """JSON has no NaN: non-finite numbers become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def run_discrepancy(model_path: str | Path, measured_path: str | Path, out_dir: str | Path,
                    seed: int = 0) -> dict:
    """The whole command as a function: returns the JSON document it wrote."""

    started = time.monotonic()

    def progress(line: str) -> None:
        print(f"discrepancy [{time.monotonic() - started:6.1f} s] {line}", file=sys.stderr,
              flush=True)

    model = load_model(model_path)
    progress(f"reading {measured_path}")
    log = read_measured_log(measured_path)
    result = analyse(model, log, seed=seed, progress=progress)
    progress("writing discrepancy.json, updated-model.yaml, discrepancy.html")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    document = _finite(result.to_json())
    (out / "discrepancy.json").write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    dump_model(result.updated_model, out / "updated-model.yaml")
    write_html(result, str(measured_path), out / "discrepancy.html")
    return document


def cmd_discrepancy(args) -> int:
    document = run_discrepancy(args.model, args.measured, args.out, args.seed)
    found = ", ".join(f["name"] for f in document["found"]) or "nothing"
    print(f"found: {found}; unexplained: {str(document['unexplained']).lower()}")
    if document["unexplained"]:
        print(f"where: {document['where']}")
    gap = document["gap"]
    print(f"gap ({gap['metric']}, {gap['unit']}): before {gap['before']:.4g}, after {gap['after']:.4g}, "
          f"noise floor {gap['noise_floor']:.4g}")
    print(f"wrote {Path(args.out) / 'discrepancy.json'}, updated-model.yaml, discrepancy.html")
    return 0
