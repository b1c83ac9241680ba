"""Which part of the reference explains a problem's key: ``gyrocal validate`` links it.

A message such as ``procedure.yaml:31: sequence[0].tests[1].dwel: unknown key`` says
what is wrong; the link (``docs/reference/procedure.md#test-sf_sweep``) says what is
allowed there and what each key means, so nobody has to learn the format from the
shipped examples.
"""

from __future__ import annotations

import re
from pathlib import Path

from gyrocal.inputs import InputError, Problem, load_yaml
from gyrocal.orchestrator.languages import (
    PROCEDURE,
    STATION,
    Either,
    Language,
    ListOf,
    Section,
    Variants,
    choose,
    section_at,
)

_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parse_key_path(text: str) -> tuple[str | int, ...]:
    """``sequence[0].tests[1].dwel`` -> ``("sequence", 0, "tests", 1, "dwel")``."""
    return tuple(int(index) if index else name for name, index in _PART.findall(text))


def doc_anchor(language: Language, path: tuple[str | int, ...], data: object) -> str | None:
    """``docs/reference/procedure.md#test-sf_sweep`` for a key path, or None if the path
    leaves the description."""
    section, key = section_at(language.root, path, data)
    if key is not None:
        value = choose(key.value, _value_at(data, path))
        if isinstance(value, Section) and value.keys:
            section = value
    if section is None:
        return None
    for owner in (STATION, PROCEDURE):
        if owner is not language and _inside(owner.root, section):
            return f"{owner.doc_file}#{section.anchor}"
    return f"{language.doc_file}#{section.anchor}"


def _value_at(data: object, path: tuple[str | int, ...]) -> object:
    for part in path:
        if isinstance(data, dict) and isinstance(part, str):
            data = data.get(part)
        elif isinstance(data, list) and isinstance(part, int) and part < len(data):
            data = data[part]
        else:
            return None
    return data


def _inside(root: object, section: Section) -> bool:
    """True when ``section`` belongs to the language whose root is ``root`` (the station's
    sections, reached through a procedure's inline ``station:``, are the station's)."""
    return root is section or (isinstance(root, Section) and root is STATION.root
                               and _reachable(root, section, set()))


def _reachable(shape: object, target: Section, seen: set[int]) -> bool:
    if shape is target:
        return True
    if id(shape) in seen:
        return False
    seen.add(id(shape))
    children: list[object] = []
    if isinstance(shape, Section):
        children = [k.value for k in shape.keys]
    elif isinstance(shape, ListOf):
        children = [shape.item]
    elif isinstance(shape, Either):
        children = list(shape.options)
    elif isinstance(shape, Variants):
        children = [s for _, s in shape.sections]
    return any(_reachable(child, target, seen) for child in children)


def with_doc_links(error: InputError, procedure_file: str) -> InputError:
    """The same problems, each followed by the reference section that explains its key."""
    documents: dict[str, object] = {}

    def data_of(file: str) -> object:
        if file not in documents:
            try:
                documents[file] = load_yaml(file).data
            except InputError:
                documents[file] = None
        return documents[file]

    procedure = Path(procedure_file).resolve()
    problems = []
    for problem in error.problems:
        link = None
        if problem.path and Path(problem.file).is_file():
            language = PROCEDURE if Path(problem.file).resolve() == procedure else STATION
            link = doc_anchor(language, parse_key_path(problem.path), data_of(problem.file))
        message = f"{problem.message} (see {link})" if link else problem.message
        problems.append(Problem(problem.file, problem.line, problem.path, message))
    return InputError(problems)
