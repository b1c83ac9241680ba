"""Problems found in an input file, reported all at once and never as a traceback.

An operator fixing a procedure at the end of the day wants every mistake in
one pass, each pointing at a file, a line and the field, in the
``file:line: path: message`` shape that editors and CI logs turn into links.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrocal.models.gyro_model import format_key_path

KeyPath = tuple[str | int, ...]
"""Where a value sits in a document: mapping keys (str) and list indices (int)."""


def format_path(path: KeyPath) -> str:
    """``("sequence", 2, "tests", 0)`` -> ``sequence[2].tests[0]`` (``""`` for the root).

    The same spelling as model-file errors, so one convention runs through every input.
    """
    return format_key_path(path)


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input file, located as precisely as the file allows."""

    file: str
    line: int | None
    path: str
    message: str

    def __str__(self) -> str:
        where = self.file if self.line is None else f"{self.file}:{self.line}"
        return f"{where}: {self.path}: {self.message}" if self.path else f"{where}: {self.message}"


class ProcedureError(Exception):
    """Bad input (exit code 2): every problem found, so one edit round fixes them all."""

    def __init__(self, problems: list[Problem]) -> None:
        if not problems:
            raise ValueError("ProcedureError needs at least one problem")
        self.problems = list(problems)
        super().__init__(str(self))

    def __str__(self) -> str:
        return "\n".join(str(problem) for problem in self.problems)


def sort_problems(problems: list[Problem]) -> list[Problem]:
    """By file (in order of first appearance), then line: the order an editor walks them."""
    file_order: dict[str, int] = {}
    for problem in problems:
        file_order.setdefault(problem.file, len(file_order))
    return sorted(problems, key=lambda p: (file_order[p.file], p.line or 0))
