"""``gyrocal sim serve``: the simulated station as standalone servers, until Ctrl-C.

For trying the drivers, a third-party tool or a second gyrocal against the
simulators without hardware. Standalone servers run on (scaled) real time:
simulated time needs the consumer in the same process (``gyrocal run --sim``).
The command prints each instrument's address and writes a copy of the
station file with those addresses filled in, so that
``gyrocal run PROC.yaml --station THAT_FILE`` drives the simulators exactly
as it would drive hardware.

It lives with the orchestrator, not with the simulators: it reads a station
file (an orchestrator concept) and starts ``instruments.sim`` servers, and
the simulators must never import the layer that drives them
(tests/test_layout.py checks the layering).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

import yaml

from gyrocal.app.library_logs import quiet_library_logs
from gyrocal.errors import EXIT_OK, BadInput, RunFaultError
from gyrocal.instruments.gyro.capture import read_capture
from gyrocal.instruments.sim.replay_pty import ReplayGyroPort
from gyrocal.instruments.sim.station_sim import SimAddresses, SimulatedStation
from gyrocal.instruments.sim.stim_identity import carries_serial
from gyrocal.models.clock import RealClock
from gyrocal.orchestrator.station import load_station

DEFAULT_STATION = Path("stations/sim.yaml")


def resolved_station_text(station_path: Path, addresses: SimAddresses,
                          replay: ReplayGyroPort | None = None) -> str:
    """The station file with ``sim`` addresses replaced by the running servers' addresses.

    With a replayed capture, the gyro's datagram, CR LF and rate are the capture's.
    """
    data = yaml.safe_load(station_path.read_text())
    data["chamber"]["address"] = addresses.chamber
    data["table"]["address"] = addresses.table
    data["gyro"]["port"] = addresses.gyro
    if addresses.supply is not None:
        data["supply"]["address"] = addresses.supply
    if replay is not None and replay.survey.layout is not None:
        data["gyro"].pop("with_temperature", None)
        data["gyro"].update(datagram=f"0x{replay.survey.layout.identifier:02X}",
                            crlf=replay.survey.layout.crlf, sample_rate_hz=replay.sample_rate_hz)
    sim = data.get("simulation")
    if isinstance(sim, dict) and "gyro_model" in sim:
        sim["gyro_model"] = str((station_path.parent / sim["gyro_model"]).resolve())
    header = (f"# Written by `gyrocal sim serve` from {station_path}: the simulators' live addresses.\n"
              "# Valid while that command runs.\n")
    return header + yaml.safe_dump(data, sort_keys=False)


def _unit_serial(args: argparse.Namespace) -> str | None:
    """The serial the simulated unit reports (``--unit-serial``): a STIM300's form, letter N and
    fourteen digits (TS1524 Table 5-15), so rehearsing against one unit, or a swap, is possible."""
    serial = getattr(args, "unit_serial", None)
    if serial is not None and not carries_serial(serial):
        raise BadInput(f"--unit-serial {serial!r}: a STIM300 serial is the letter N and fourteen "
                       "digits (TS1524 Table 5-15), e.g. N25580000000123")
    return serial


def cmd_sim_serve(args: argparse.Namespace) -> int:
    quiet_library_logs(getattr(args, "debug", False))
    station_path = Path(args.station) if args.station else DEFAULT_STATION
    station = load_station(station_path)
    try:
        speed = float(args.speed)
        clock = RealClock(speed)
    except ValueError as exc:
        raise BadInput(f"--speed: {exc}") from None
    replay = None
    if getattr(args, "replay_gyro", None):
        try:
            replay = ReplayGyroPort(read_capture(args.replay_gyro), clock, source=args.replay_gyro)
        except ValueError as exc:
            raise BadInput(f"--replay-gyro {exc}") from None
    try:
        simulated = SimulatedStation(station, clock, seed=args.seed, gyro_port=replay,
                                     unit_serial=_unit_serial(args))
    except ValueError as exc:
        if replay is not None:
            replay.stop()
        raise BadInput(str(exc)) from None
    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        with simulated:
            addresses = simulated.addresses
            out = Path(args.write_station) if args.write_station else None
            if out is not None:
                out.write_text(resolved_station_text(station_path, addresses, replay))
            print(f"simulated station {station.name!r} (real time × {speed:g}), Ctrl-C to stop")
            print(f"  chamber ({station.chamber.driver}): {addresses.chamber}")
            print(f"  table   ({station.table.driver}): {addresses.table}")
            print(f"  gyro    ({station.gyro.driver}): {addresses.gyro}")
            if station.supply is not None:
                print(f"  supply  ({station.supply.driver}): {addresses.supply}")
            if replay is not None:
                print(f"    replaying {args.replay_gyro}: {replay.survey.describe()} at "
                      f"{replay.sample_rate_hz:g} Hz, {replay.duration_s:g} s, looped")
            if out is not None:
                print(f"  station file with these addresses: {out}")
            sys.stdout.flush()
            try:
                while not stop.wait(0.2):
                    if simulated.gyro_port.error is not None:
                        raise RunFaultError(f"simulated gyro stopped: {simulated.gyro_port.error}")
            except KeyboardInterrupt:
                pass
    finally:
        signal.signal(signal.SIGTERM, previous)
    print("simulators stopped")
    return EXIT_OK
