"""The one input layer: every file a user hands gyrocal is read here, within limits.

Procedures, stations, gyro-model files, measured logs and run folders come
from people and other programs, so a file may be anything: a FIFO that never
ends (``station: /tmp/pipe``), a device (``/dev/zero``), a binary, a private
file that must not be echoed in an error, a ten-line YAML "alias bomb" that
expands to gigabytes, or nesting deep enough to exhaust Python's stack. The
limits below turn each of those into one clear :class:`InputError` (exit 2)
naming the file and line, never a hang, a traceback or the file's contents:

* regular files only, opened non-blocking and checked with ``fstat`` (a FIFO
  or a device is refused without reading a byte);
* a size limit for YAML documents, readable UTF-8 text, no NUL bytes;
* nesting depth and total expanded values bounded (alias bombs);
* duplicate keys, non-scalar keys and non-standard tags rejected with the
  line where they are.

This module depends on PyYAML and the standard library only, so every layer
(the physics in ``models`` included) loads its files through it.

``yaml.safe_load`` throws the node marks away, so a schema error could only
say *what* is wrong, not *where*. Here the document is composed with
``yaml.SafeLoader`` and turned into plain data by hand, recording the file and
line of every key path (``sequence[2].tests[0].rates_dps[3]``).

``!include other.yaml`` splices another file in place of a value. Includes
are resolved relative to the including file and may not leave the folder of
the top-level document (symlinks resolved), so a procedure folder copied into
a run's manifest is self-contained.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from gyrocal.errors import BadInput

KeyPath = tuple[str | int, ...]
"""Where a value sits in a document: mapping keys (str) and list indices (int)."""

#: A procedure, station or model file is a few kilobytes; 4 MiB is generous and
#: keeps a mistaken multi-gigabyte file from being read at all.
MAX_YAML_BYTES = 4 * 1024 * 1024
#: Deeper than any real document; far below what exhausts Python's stack.
MAX_DEPTH = 64
#: How much of a CSV log is checked for being text before it is parsed.
TEXT_HEAD_BYTES = 64 * 1024


#: A folder holding this is a gyrocal project (procedures/ and stations/ side by side).
PROJECT_MARKER = "stations"
ALLOW_OUTSIDE_FLAG = "--allow-outside-paths"


def outside_reference(referring: Path, target: Path) -> str | None:
    """Why ``target`` (named inside the file ``referring``) may not be read, or None if it may.

    A file a procedure or station names must lie in the referring file's folder, in its
    project (the nearest folder above it holding ``stations/``) or in the working folder;
    anything else - ``station: /etc/shadow`` - needs :data:`ALLOW_OUTSIDE_FLAG`. The check
    is on the resolved path (``..`` and symlinks followed) and happens before a byte is read,
    so a refused file's contents can never reach a message.
    """
    resolved = target.resolve()
    folder = referring.resolve().parent
    roots = [folder, Path.cwd().resolve()]
    project = next((p for p in (folder, *folder.parents) if (p / PROJECT_MARKER).is_dir()), None)
    if project is not None:
        roots.insert(1, project)
    if any(resolved.is_relative_to(root) for root in roots):
        return None
    names = ", ".join(dict.fromkeys(str(root) for root in roots))
    return (f"{resolved} is outside {names} (the referring file's folder, its project and the "
            f"working folder); give {ALLOW_OUTSIDE_FLAG} to read it")


def format_key_path(path: tuple) -> str:
    """``("effects", 1, "tau_s")`` -> ``effects[1].tau_s``: how every input error names a field."""
    text = ""
    for part in path:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


format_path = format_key_path


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


class InputError(BadInput):
    """Bad input (exit code 2): every problem found, so one edit round fixes them all."""

    def __init__(self, problems: list[Problem]) -> None:
        if not problems:
            raise ValueError("InputError needs at least one problem")
        self.problems = list(problems)
        super().__init__(str(self))

    def __str__(self) -> str:
        return "\n".join(str(problem) for problem in self.problems)

    @classmethod
    def one(cls, file: str, message: str, line: int | None = None) -> InputError:
        return cls([Problem(file, line, "", message)])


# -- files -------------------------------------------------------------------------------

def _kind_of(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def open_regular_file(path: str | os.PathLike[str], display: str | None = None) -> int:
    """A read-only descriptor of ``path`` if it is a regular file; else :class:`InputError`.

    Opened with ``O_NONBLOCK`` so a FIFO with no writer cannot hang the open; the
    type is judged with ``fstat`` on what was actually opened (no check-then-open race).
    """
    display = os.fspath(path) if display is None else display
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputError.one(display, "file not found") from None
    except OSError as error:
        raise InputError.one(display, f"cannot read the file: {error.strerror or error}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise InputError.one(display, f"is {_kind_of(mode)}; expected a regular file")
    return fd


def require_regular_file(path: str | os.PathLike[str], display: str | None = None) -> None:
    os.close(open_regular_file(path, display))


def _read_at_most(fd: int, limit: int) -> bytes:
    chunks: list[bytes] = []
    size = 0
    while size <= limit:
        chunk = os.read(fd, min(1 << 20, limit + 1 - size))
        if not chunk:
            break
        chunks.append(chunk)
        size += len(chunk)
    return b"".join(chunks)


def _check_text(data: bytes, display: str, what: str, truncated: bool) -> str:
    """UTF-8 text without NUL bytes, or :class:`InputError` naming the line (never the bytes)."""
    nul = data.find(b"\0")
    if nul >= 0:
        raise InputError.one(display, f"cannot read the file: a NUL byte (binary content); not {what}",
                             data.count(b"\n", 0, nul) + 1)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        if truncated and error.start >= len(data) - 3 and error.reason == "unexpected end of data":
            return data[:error.start].decode("utf-8")
        raise InputError.one(display, f"cannot read the file: not UTF-8 text (byte {error.start}); not {what}",
                             data.count(b"\n", 0, error.start) + 1) from None


def read_text_file(path: str | os.PathLike[str], display: str | None = None, *,
                   max_bytes: int = MAX_YAML_BYTES, what: str = "a YAML file") -> str:
    """The whole file as text, within ``max_bytes``; every refusal is an :class:`InputError`."""
    display = os.fspath(path) if display is None else display
    fd = open_regular_file(path, display)
    try:
        data = _read_at_most(fd, max_bytes)
    except OSError as error:
        raise InputError.one(display, f"cannot read the file: {error.strerror or error}") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise InputError.one(display, f"larger than {max_bytes // 1024} KiB; not {what}?")
    return _check_text(data, display, what, truncated=False)


def check_text_head(path: str | os.PathLike[str], display: str | None = None, *,
                    what: str = "a CSV log") -> None:
    """A large text log: regular file, and its first bytes are text (binary is refused early)."""
    display = os.fspath(path) if display is None else display
    fd = open_regular_file(path, display)
    try:
        data = _read_at_most(fd, TEXT_HEAD_BYTES - 1)
    finally:
        os.close(fd)
    _check_text(data, display, what, truncated=True)


class _LimitedLoader(yaml.SafeLoader):
    """SafeLoader whose composer refuses nesting deeper than :data:`MAX_DEPTH`.

    PyYAML composes recursively: a few thousand ``[`` exhaust the stack. The
    limit is checked on the way down, before any recursion can go deep.
    """

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Node | None, index: object) -> Node | None:
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise yaml.composer.ComposerError(
                    None, None, f"nested deeper than {MAX_DEPTH} levels", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


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
    """Load ``path`` or raise :class:`InputError` listing every problem found."""
    display = os.fspath(path)
    resolved = Path(display).resolve()
    builder = _Builder(root_dir=resolved.parent)
    document = YamlDocument(file=display, path=resolved, data=None)
    document.data = builder.load_file(resolved, display, (), document, stack=())
    if builder.problems:
        raise InputError(builder.problems)
    return document


def _describe_yaml_error(error: yaml.YAMLError) -> str:
    if isinstance(error, yaml.reader.ReaderError):
        return f"unprintable character #x{error.character:04x} (not a text YAML file?)" \
            if isinstance(error.character, int) else "unreadable character"
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
            text = read_text_file(path, display)
        except InputError as error:
            self.problems.extend(
                Problem(p.file, p.line, format_path(key_path), p.message) for p in error.problems)
            return None
        document.files.append(path)
        loader: _LimitedLoader | None = None
        try:
            loader = _LimitedLoader(text)     # its reader rejects unprintable characters here
            node = loader.get_single_node()
            if node is None:
                return None
            return self.build(node, loader, display, path, key_path, document, (*stack, path), set())
        except yaml.YAMLError as error:
            mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
            line = mark.line + 1 if mark is not None else None
            if isinstance(error, yaml.reader.ReaderError):
                line = text.count("\n", 0, error.position) + 1
            self.problems.append(Problem(display, line, format_path(key_path), _describe_yaml_error(error)))
            return None
        finally:
            if loader is not None:
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
        if any(ord(c) < 32 or ord(c) == 127 for c in target_text):
            self.problems.append(Problem(display, line, where, f"!include {target_text!r}: a file "
                                         "name cannot hold a NUL or control character"))
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
        loader: _LimitedLoader,
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
            return self.build_scalar(node, loader, display, path, key_path, document, stack)

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

    def build_scalar(self, node: ScalarNode, loader: _LimitedLoader, display: str, path: Path,
                     key_path: KeyPath, document: YamlDocument, stack: tuple[Path, ...]) -> Any:
        """A scalar: an ``!include``, or a value of a standard tag (anything else is refused)."""
        line = node.start_mark.line + 1
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

    def build_mapping(
        self,
        node: MappingNode,
        loader: _LimitedLoader,
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


