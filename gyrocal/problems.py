"""Problems found in an input file, reported all at once and never as a traceback.

An operator fixing a procedure at the end of the day wants every mistake in
one pass, each pointing at a file, a line and the field, in the
``file:line: path: message`` shape that editors and CI logs turn into links.
"""

from __future__ import annotations

from gyrocal.inputs import InputError, KeyPath, Problem, format_path

#: The orchestrator's long-standing name for bad input (exit 2); the class lives in
#: the input layer, which the model files and measured logs share.
ProcedureError = InputError

__all__ = ["KeyPath", "Problem", "ProcedureError", "format_path", "sort_problems"]


def sort_problems(problems: list[Problem]) -> list[Problem]:
    """By file (in order of first appearance), then line: the order an editor walks them."""
    file_order: dict[str, int] = {}
    for problem in problems:
        file_order.setdefault(problem.file, len(file_order))
    return sorted(problems, key=lambda p: (file_order[p.file], p.line or 0))
