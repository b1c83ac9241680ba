"""docs/tutorial.md, followed literally: every ``sh`` block, in order, in an empty folder.

The blocks are joined into one bash script (``set -euo pipefail``: a command that fails
stops it, as it would stop a reader) and run with only ``GYROCAL_HOME`` set to this
clone, as the tutorial's first step asks. The run is a real dry run against the
simulated instruments; the last command, ``gyrocal verify``, must say OK.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest
from pypdf import PdfReader

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO / "docs" / "tutorial.md"


def shell_blocks(markdown: str) -> list[str]:
    return re.findall(r"```sh\n(.*?)```", markdown, re.S)


@pytest.mark.slow
def test_the_tutorial_runs_from_an_empty_folder_to_verify_ok(tmp_path: Path) -> None:
    blocks = shell_blocks(TUTORIAL.read_text(encoding="utf-8"))
    assert len(blocks) >= 8
    assert blocks[-1].strip() == "gyrocal verify runs/first"
    script = "set -euo pipefail\n" + "\n".join(blocks)
    env = {k: v for k, v in os.environ.items() if not k.startswith("GYROCAL")}
    env["GYROCAL_HOME"] = str(REPO)
    env["PATH"] = os.defpath            # the tutorial puts gyrocal on PATH itself
    assert list(tmp_path.iterdir()) == []
    done = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=280)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out = done.stdout
    assert "first-calibration.yaml: OK" in out
    assert "run complete: runs/first" in out
    assert "  PASS  SF nonlinearity (RMS)" in out and "BLOCKED" not in out
    assert any(line.startswith("runs/first: OK") for line in out.splitlines()), out[-2000:]
    assert "certificate MY-2026-0001" in out        # verify checked the journaled certificate
    project = tmp_path / "my-gyro"
    pdf = PdfReader(project / "runs" / "first" / "report" / "certificate.pdf")
    assert "MY-2026-0001" in pdf.pages[0].extract_text()
    assert (project / "runs" / "first" / "report" / "results.json").is_file()
