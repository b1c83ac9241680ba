"""The one list of drivers: gyrocal's own plus those installed packages publish.

A package adds drivers by declaring, in its ``pyproject.toml``::

    [project.entry-points."gyrocal.drivers"]
    my_chamber = "my_package.gyrocal_driver:SPEC"

where ``SPEC`` is a :class:`~gyrocal.instruments.driver_spec.DriverSpec` (or a
sequence of them). Entry points are found with :mod:`importlib.metadata`,
the standard mechanism, so an installed distribution is all it takes.

A plug-in that cannot be loaded, or that reuses a name, never stops gyrocal:
it is left out and its problem is kept in :attr:`DriverRegistry.problems`,
which the message for an unknown driver repeats (the lab then sees *why* its
driver is missing, not just that it is).
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import dataclass, replace
from importlib import metadata

from gyrocal.instruments.builtin_drivers import BUILTIN_DRIVERS
from gyrocal.instruments.driver_spec import DriverSpec, Role

ENTRY_POINT_GROUP = "gyrocal.drivers"


class UnknownDriver(KeyError):
    """A station names a driver nobody registered (the message lists those that exist)."""

    def __str__(self) -> str:
        return str(self.args[0])


@dataclass(frozen=True)
class DriverRegistry:
    specs: tuple[DriverSpec, ...]
    #: plug-ins left out, one sentence each (distribution, entry point, why)
    problems: tuple[str, ...] = ()

    def names(self, role: Role) -> tuple[str, ...]:
        return tuple(s.name for s in self.specs if s.role is role)

    def for_role(self, role: Role) -> tuple[DriverSpec, ...]:
        return tuple(s for s in self.specs if s.role is role)

    def get(self, role: Role, name: str) -> DriverSpec:
        for spec in self.specs:
            if spec.role is role and spec.name == name:
                return spec
        known = ", ".join(self.names(role)) or "none"
        hint = f" (plug-ins left out: {'; '.join(self.problems)})" if self.problems else ""
        raise UnknownDriver(f"no {role.value} driver {name!r}; known: {known}{hint}")


def _entry_points() -> Iterable[metadata.EntryPoint]:
    return metadata.entry_points(group=ENTRY_POINT_GROUP)


def _load(entry: metadata.EntryPoint) -> tuple[list[DriverSpec], str | None]:
    origin = entry.dist.name if entry.dist is not None else entry.value
    where = f"entry point {entry.name!r} = {entry.value!r} of {origin}"
    try:
        published = entry.load()
    except Exception as exc:  # a broken plug-in must not stop the lab's other runs
        return [], f"{where}: cannot be loaded ({type(exc).__name__}: {exc})"
    items = [published] if isinstance(published, DriverSpec) else published
    if not isinstance(items, (list, tuple)) or not all(isinstance(i, DriverSpec) for i in items):
        return [], f"{where}: is not a DriverSpec or a sequence of them"
    return [_with_origin(spec, origin) for spec in items], None


def _with_origin(spec: DriverSpec, origin: str) -> DriverSpec:
    return replace(spec, origin=origin)


def build_registry(extra: Iterable[metadata.EntryPoint] | None = None) -> DriverRegistry:
    """gyrocal's drivers plus every ``gyrocal.drivers`` entry point (``extra``: instead of the installed)."""
    specs = list(BUILTIN_DRIVERS)
    problems: list[str] = []
    for entry in (_entry_points() if extra is None else extra):
        loaded, problem = _load(entry)
        if problem:
            problems.append(problem)
        for spec in loaded:
            if any(s.role is spec.role and s.name == spec.name for s in specs):
                problems.append(f"{spec.origin}: {spec.role.value} driver {spec.name!r} is "
                                "already registered; left out")
                continue
            specs.append(spec)
    return DriverRegistry(tuple(specs), tuple(problems))


@functools.lru_cache(maxsize=1)
def registry() -> DriverRegistry:
    """The drivers of this process (entry points read once)."""
    return build_registry()
