"""A procedure for a dry run on one of the simulated stations, and the run itself.

The step-kind tests (magnetic, tilt linearity, table interference, IMU) share the
same safety limits, ramp, soak and data-quality rules; only the unit, the
station, a few defaults and the sequence differ. Writing that header once keeps
their procedures comparable and the tests about what each step kind does.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from gyrocal.cli import EXIT_OK, main

REPO = Path(__file__).resolve().parents[2]


def sim_procedure(name: str, uut: str, station: Path | str, defaults: Sequence[str],
                  body: str) -> str:
    """Procedure text: ``uut`` is the unit's ``model: …, serial: …``; ``defaults`` the lines
    between the soak and ``sample_rate_hz: 250``; ``body`` everything after data_quality."""
    default_lines = "".join(f"  {line}\n" for line in defaults)
    return (
        "version: 1\n"
        f"name: {name}\n"
        f"unit_under_test: {{{uut}, output_units: deg/s, nominal_scale_factor: 1.0}}\n"
        f"station: {station}\n"
        "safety:\n"
        "  chamber: {min_temp_c: -15.0, max_temp_c: 45.0, max_ramp_c_per_min: 5.0}\n"
        "  table: {max_rate_dps: 300.0, max_accel_dps2: 100.0}\n"
        "defaults:\n"
        "  ramp_c_per_min: 5.0\n"
        "  soak: {tolerance_c: 0.5, hold: 1 min, max_wait: 1 h}\n"
        f"{default_lines}"
        "  sample_rate_hz: 250\n"
        "data_quality: {max_lost_frame_fraction: 0.001, max_step_repeats: 2}\n"
        f"{body}"
    )


def dry_run(procedure: Path, out: Path, *args: str) -> Path:
    """``gyrocal run procedure --sim --out out [args]``, which must succeed; the run folder."""
    assert main(["run", str(procedure), "--sim", "--out", str(out), *args]) == EXIT_OK
    return out


def station_file(tmp: Path, station: Path, text: str | None) -> Path:
    """``station``, or when ``text`` is given (an edited copy of it) that text written to
    tmp/station.yaml with its ``../gyro-models/`` references made absolute."""
    if text is None:
        return station
    path = tmp / "station.yaml"
    path.write_text(text.replace("../gyro-models/", f"{REPO}/gyro-models/"))
    return path


def write_procedure(tmp: Path, text: str) -> Path:
    """``text`` written to tmp/p.yaml."""
    path = tmp / "p.yaml"
    path.write_text(text)
    return path
