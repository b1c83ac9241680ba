"""What a caller asks of ``run`` and ``resume``, typed: the CLI and the demo build the same request.

Before, the demo built an ``argparse.Namespace`` by hand to call the command
handler, so a new option was a silent ``AttributeError`` waiting in the demo.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Called with each ``SimulatedStation`` right after ``--sim`` starts it, before any
#: driver connects (``gyrocal.cli.main(..., on_sim_started=)``). Fault-injection tests
#: arm simulator faults through it, so faults reach the very simulators a real
#: ``run``/``resume`` talks to. None in normal use.
SimStarted = Callable[[Any], None]


@dataclass(frozen=True)
class RunRequest:
    """``gyrocal run PROCEDURE``: the procedure, where to run it, and how."""

    procedure: Path
    station: Path | None = None
    sim: bool = False
    sim_station: Path | None = None     # --sim-station: another station file for the dry run
    out: Path | None = None
    speed: str | None = None            # None: "max" with --sim, "1" on real instruments
    seed: int | None = None
    operator: str | None = None
    inject: tuple[str, ...] = ()
    signing_key: str | None = None
    allow_outside_paths: bool = False
    debug: bool = False
    on_sim_started: SimStarted | None = None

    @property
    def station_path(self) -> Path | None:
        return self.sim_station if self.sim and self.sim_station else self.station

    @property
    def speed_text(self) -> str:
        return self.speed if self.speed is not None else ("max" if self.sim else "1")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RunRequest:
        def path(value: str | None) -> Path | None:
            return None if value is None else Path(value)
        return cls(procedure=Path(args.procedure), station=path(args.station), sim=args.sim,
                   sim_station=path(args.sim_station), out=path(args.out), speed=args.speed,
                   seed=args.seed, operator=args.operator, inject=tuple(args.inject or ()),
                   signing_key=args.signing_key, allow_outside_paths=args.allow_outside_paths,
                   debug=args.debug, on_sim_started=args.on_sim_started)


@dataclass(frozen=True)
class ResumeRequest:
    """``gyrocal resume RUN_DIR``: the run folder, and what may differ from the first session."""

    run_dir: Path
    speed: str | None = None            # None: the speed the run started with
    signing_key: str | None = None
    debug: bool = False
    on_sim_started: SimStarted | None = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ResumeRequest:
        return cls(run_dir=Path(args.run_dir), speed=args.speed, signing_key=args.signing_key,
                   debug=args.debug, on_sim_started=args.on_sim_started)
