"""Safe YAML loading that remembers where every value came from.

``yaml.safe_load`` throws the node marks away, so a schema error could only
say *what* is wrong, not *where*. Here the document is composed with
``yaml.SafeLoader`` and turned into plain data by hand, recording the file and
line of every key path (``sequence[2].tests[0].rates_dps[3]``). On the way it
rejects what ``safe_load`` silently accepts but an operator never means:
duplicate keys (the second would win without a word), non-scalar keys and
tags other than the standard ones.

``!include other.yaml`` splices another file in place of a value. Includes
are resolved relative to the including file and may not leave the folder of
the top-level document (symlinks resolved), so a procedure folder copied into
a run's manifest is self-contained.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from gyrocal.orchestrator.problems import KeyPath, Problem, ProcedureError, format_path

INCLUDE_TAG = "!include"
MAX_INCLUDE_DEPTH = 8
# Aliases can make a small file expand into a huge tree ("billion laughs").
MAX_VALUES = 200_000

_STANDARD_SCALAR_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:timestamp",
}
_MAP_TAG = "tag:yaml.org,2002:map"
_SEQ_TAG = "tag:yaml.org,2002:seq"
_MERGE_TAG = "tag:yaml.org,2002:merge"


@dataclass(frozen=True)
class Location:
    file: str
    line: int


@dataclass
class YamlDocument:
    """Plain data (dicts, lists, scalars) plus the location of every key path."""

    file: str                      # the name to show in messages, as the user gave it
    path: Path                     # resolved path of the top-level file
    data: Any
    locations: dict[KeyPath, Location] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)   # top-level file, then every include

    def where(self, path: KeyPath) -> Location:
        """Location of ``path``, or of its nearest ancestor (a missing key is reported
        where its parent mapping is)."""
        for end in range(len(path), -1, -1):
            found = self.locations.get(tuple(path[:end]))
            if found is not None:
                return found
        return Location(self.file, 1)

    def problem(self, path: KeyPath, message: str) -> Problem:
        location = self.where(path)
        return Problem(location.file, location.line, format_path(path), message)


def load_yaml(path: str | os.PathLike[str]) -> YamlDocument:
    """Load ``path`` or raise :class:`ProcedureError` listing every problem found."""
    display = os.fspath(path)
    resolved = Path(display).resolve()
    builder = _Builder(root_dir=resolved.parent)
    document = YamlDocument(file=display, path=resolved, data=None)
    document.data = builder.load_file(resolved, display, (), document, stack=())
    if builder.problems:
        raise ProcedureError(builder.problems)
    return document


def _describe_yaml_error(error: yaml.YAMLError) -> str:
    if isinstance(error, yaml.MarkedYAMLError):
        parts = [part for part in (error.context, error.problem) if part]
        return "malformed YAML: " + "; ".join(parts) if parts else "malformed YAML"
    return f"malformed YAML: {error}"


class _Builder:
    def __init__(self, root_dir: Path) -> None:
        self.root_dir = root_dir
        self.problems: list[Problem] = []
        self.values = 0

    # -- files -----------------------------------------------------------------
    def load_file(
        self,
        path: Path,
        display: str,
        key_path: KeyPath,
        document: YamlDocument,
        stack: tuple[Path, ...],
    ) -> Any:
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            self.problems.append(Problem(display, None, format_path(key_path), "file not found"))
            return None
        except (OSError, UnicodeDecodeError) as error:
            reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
            self.problems.append(
                Problem(display, None, format_path(key_path), f"cannot read the file: {reason}")
            )
            return None
        document.files.append(path)
        loader = yaml.SafeLoader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            return self.build(node, loader, display, path, key_path, document, (*stack, path), set())
        except yaml.YAMLError as error:
            mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
            line = mark.line + 1 if mark is not None else None
            self.problems.append(Problem(display, line, format_path(key_path), _describe_yaml_error(error)))
            return None
        finally:
            loader.dispose()

    def include(
        self,
        node: ScalarNode,
        display: str,
        path: Path,
        key_path: KeyPath,
        document: YamlDocument,
        stack: tuple[Path, ...],
    ) -> Any:
        line = node.start_mark.line + 1
        where = format_path(key_path)
        target_text = str(node.value).strip()
        if not target_text:
            self.problems.append(Problem(display, line, where, "!include needs a file name"))
            return None
        target = (path.parent / target_text).resolve()
        if not target.is_relative_to(self.root_dir):
            self.problems.append(
                Problem(
                    display,
                    line,
                    where,
                    f"!include {target_text} leaves the folder {self.root_dir} "
                    f"(resolves to {target}); includes must stay inside it",
                )
            )
            return None
        if target in stack:
            self.problems.append(Problem(display, line, where, f"!include {target_text} includes itself"))
            return None
        if len(stack) > MAX_INCLUDE_DEPTH:
            self.problems.append(
                Problem(display, line, where, f"includes nested deeper than {MAX_INCLUDE_DEPTH}")
            )
            return None
        included_display = os.path.normpath(os.path.join(os.path.dirname(display), target_text))
        return self.load_file(target, included_display, key_path, document, stack)

    # -- nodes -----------------------------------------------------------------
    def build(
        self,
        node: Node,
        loader: yaml.SafeLoader,
        display: str,
        path: Path,
        key_path: KeyPath,
        document: YamlDocument,
        stack: tuple[Path, ...],
        active: set[int],
    ) -> Any:
        line = node.start_mark.line + 1
        document.locations.setdefault(key_path, Location(display, line))
        self.values += 1
        if self.values > MAX_VALUES:
            if self.values == MAX_VALUES + 1:
                self.problems.append(
                    Problem(display, line, format_path(key_path),
                            f"the document expands to more than {MAX_VALUES} values (alias bomb?)")
                )
            return None
        if id(node) in active:
            self.problems.append(Problem(display, line, format_path(key_path), "recursive alias"))
            return None

        if isinstance(node, ScalarNode):
            if node.tag == INCLUDE_TAG:
                return self.include(node, display, path, key_path, document, stack)
            if node.tag not in _STANDARD_SCALAR_TAGS:
                self.problems.append(
                    Problem(display, line, format_path(key_path), f"unsupported YAML tag {node.tag}")
                )
                return None
            try:
                return loader.construct_object(node, deep=True)
            except (ValueError, OverflowError) as error:   # e.g. the date 2027-13-45
                self.problems.append(
                    Problem(display, line, format_path(key_path),
                            f"cannot read {node.value!r}: {error}")
                )
                return None

        active = active | {id(node)}
        if isinstance(node, SequenceNode):
            if node.tag != _SEQ_TAG:
                self.problems.append(
                    Problem(display, line, format_path(key_path), f"unsupported YAML tag {node.tag}")
                )
                return None
            return [
                self.build(item, loader, display, path, (*key_path, index), document, stack, active)
                for index, item in enumerate(node.value)
            ]

        if isinstance(node, MappingNode):
            if node.tag != _MAP_TAG:
                self.problems.append(
                    Problem(display, line, format_path(key_path), f"unsupported YAML tag {node.tag}")
                )
                return None
            return self.build_mapping(node, loader, display, path, key_path, document, stack, active)

        self.problems.append(Problem(display, line, format_path(key_path), "unsupported YAML node"))
        return None

    def build_mapping(
        self,
        node: MappingNode,
        loader: yaml.SafeLoader,
        display: str,
        path: Path,
        key_path: KeyPath,
        document: YamlDocument,
        stack: tuple[Path, ...],
        active: set[int],
    ) -> dict[str, Any]:
        # Duplicates are judged on the keys written in this mapping; keys brought
        # in by a merge (<<: *anchor) may legitimately be overridden.
        first_line: dict[str, int] = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, ScalarNode) or key_node.tag == _MERGE_TAG:
                continue
            key = str(key_node.value)
            key_line = key_node.start_mark.line + 1
            if key in first_line:
                self.problems.append(
                    Problem(display, key_line, format_path((*key_path, key)),
                            f"duplicate key (first given on line {first_line[key]})")
                )
            else:
                first_line[key] = key_line
        loader.flatten_mapping(node)   # resolves merge keys; raises a marked error if malformed

        result: dict[str, Any] = {}
        for key_node, value_node in node.value:
            key_line = key_node.start_mark.line + 1
            if not isinstance(key_node, ScalarNode):
                self.problems.append(
                    Problem(display, key_line, format_path(key_path),
                            "a key must be a plain name, not a list or a mapping")
                )
                continue
            # Keys are names: `1:` or `true:` become the text written, so the schema
            # can call them unknown keys instead of crashing on a non-string.
            key = str(key_node.value)
            child_path = (*key_path, key)
            document.locations[child_path] = Location(display, key_line)
            result[key] = self.build(
                value_node, loader, display, path, child_path, document, stack, active
            )
            # the value may start on a later line; the key's line is where people look
            document.locations[child_path] = Location(display, key_line)
        return result


__all__ = ["Location", "Problem", "ProcedureError", "YamlDocument", "load_yaml", "format_path"]
