"""``gyrocal decode CAPTURE --driver stim300``: a unit's recorded bytes become a measured log.

What a lab does with bytes captured from a real unit (or from someone
else's): find which datagram the unit sends and at what rate (TS1524
Table 5-21 identifiers checked by CRC; the rate from the counter, which
counts 2000 Hz internal samples, §7.5.2.2.18), decode every datagram with
the driver's own decoder, and write the contract's measured log
(gyro-model.md "Measured log") plus every channel the datagram carries.

A capture has no table and no chamber: ``table_rate_dps`` is the rate the
unit was turned at (``--table-rate-dps``, default 0, at rest) and
``chamber_temp_c`` is ``--chamber-temp-c`` or, where the datagram carries
temperatures, the unit-under-test gyro's own temperature; with neither it
is the standard laboratory atmosphere, 23 °C (ISO 554), and the summary
says it was assumed.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from gyrocal.app.decode_specials import (
    SpecialInCapture,
    configuration_fields,
    describe_special,
    place_specials,
    special_figures,
)
from gyrocal.errors import EXIT_OK, BadInput
from gyrocal.instruments.gyro.capture import read_capture
from gyrocal.instruments.gyro.configuration import UnitConfiguration
from gyrocal.instruments.gyro.datagram import (
    DEFAULT_LSB,
    DecodedFrames,
    FrameDecoder,
    axis_index,
    concat_decoded,
    flagged,
)
from gyrocal.instruments.gyro.datagram_types import (
    DEFAULT_ACCELEROMETER_RANGE_G,
    INTERNAL_RATE_HZ,
)
from gyrocal.instruments.gyro.special_datagrams import Found, cut_specials
from gyrocal.instruments.gyro.survey import survey_stream
from gyrocal.record.run_folder import SAMPLE_FLAG_GYRO_FLAGGED

DRIVERS = ("stim300",)
ASSUMED_AMBIENT_C = 23.0            # ISO 554 standard atmosphere, when nothing else is known
_SURVEY_BYTES = 1 << 18             # enough for thousands of datagrams of any type
#: a unit at rest feels 1 g; a static magnitude outside this band suggests a wrong range
_GRAVITY_BAND_G = (0.8, 1.2)


@dataclass(frozen=True)
class DecodeOptions:
    accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G
    rate_lsb: float = DEFAULT_LSB
    axis: str = "x"
    table_rate_dps: float = 0.0
    chamber_temp_c: float | None = None


@dataclass
class DecodedCapture:
    """The whole capture decoded, and what was found about the stream."""

    frames: DecodedFrames
    datagram_label: str
    datagram_id: int
    crlf: bool
    counter_step: int
    crc_errors: int
    garbage_bytes: int
    tail_bytes: int
    bytes_total: int
    specials: list[SpecialInCapture]

    @property
    def sample_rate_hz(self) -> float:
        return INTERNAL_RATE_HZ / self.counter_step


def decode_capture(data: bytes, source: str, options: DecodeOptions) -> DecodedCapture:
    """Identify the datagram and rate from the bytes, then decode all of them.

    Special datagrams (start-up, or answers to ``N``/``I``/``C``) are cut out
    first with the driver's search, so they are not garbage, and the counter gap
    across an answer counts as replaced datagrams, not lost ones.
    """
    kept, found, _ = cut_specials(data)
    survey = survey_stream(kept[:_SURVEY_BYTES])
    if survey.layout is None or survey.frames_valid < 2 or survey.counter_step is None:
        raise BadInput(f"{source}: no STIM300 normal-mode datagram (TS1524 Table 5-21) with a "
                       f"valid CRC found in the first {min(len(kept), _SURVEY_BYTES)} bytes")
    if survey.counter_step > 255:
        raise BadInput(f"{source}: the counter does not advance between datagrams; "
                       "the rate cannot be read from it")
    layout = survey.layout
    decoder = FrameDecoder(lsb=options.rate_lsb, crlf=layout.crlf, datagram=layout.identifier,
                           counter_step=survey.counter_step,
                           accelerometer_range_g=options.accelerometer_range_g)
    frames, frames_before = _decode_between(data, found, decoder)
    specials = place_specials(found, [data[f.start] for f in found], frames_before, frames.counter,
                              survey.counter_step)
    frames.lost_frames = decoder.total_lost_frames - sum(s.replaced_frames or 0 for s in specials)
    return DecodedCapture(frames, layout.kind.label(), layout.identifier, layout.crlf,
                          survey.counter_step, decoder.total_crc_errors, decoder.total_garbage_bytes,
                          decoder.pending_bytes, len(data), specials)


def _decode_between(data: bytes, found: list[Found],
                    decoder: FrameDecoder) -> tuple[DecodedFrames, list[int]]:
    """The bytes around the special datagrams decoded as one stream, and how many
    normal-mode datagrams precede each special."""
    view = memoryview(data)
    parts: list[DecodedFrames] = []
    frames_before: list[int] = []
    at = 0
    for hit in found:
        parts.append(decoder.feed(view[at:hit.start]))
        frames_before.append(decoder.total_frames)
        at = hit.end
    parts.append(decoder.feed(view[at:]))
    return concat_decoded(parts, decoder.layout), frames_before


def log_columns(capture: DecodedCapture, options: DecodeOptions) -> tuple[dict[str, np.ndarray], str]:
    """The measured-log columns and where ``chamber_temp_c`` came from."""
    frames = capture.frames
    axis = axis_index(options.axis)
    n = len(frames)
    columns: dict[str, np.ndarray] = {
        "t_s": (frames.index - frames.index[0]) / capture.sample_rate_hz,
        "table_rate_dps": np.full(n, float(options.table_rate_dps)),
    }
    if options.chamber_temp_c is not None:
        columns["chamber_temp_c"] = np.full(n, float(options.chamber_temp_c))
        source = "--chamber-temp-c"
    elif frames.temp_c is not None:
        columns["chamber_temp_c"] = frames.temp_c[:, axis].copy()
        source = f"the {options.axis} gyro's temperature in the datagram"
    else:
        columns["chamber_temp_c"] = np.full(n, ASSUMED_AMBIENT_C)
        source = f"assumed {ASSUMED_AMBIENT_C:g} °C (not in the capture; give --chamber-temp-c)"
    columns["gyro"] = frames.rate[:, axis]
    if frames.temp_c is not None:
        columns["sensor_temp_c"] = frames.temp_c[:, axis]
    columns.update(gyro_x=frames.rate[:, 0], gyro_y=frames.rate[:, 1], gyro_z=frames.rate[:, 2],
                   gyro_status=frames.status,
                   status=np.where(flagged(frames.status, axis), SAMPLE_FLAG_GYRO_FLAGGED, 0))
    if frames.channels is not None:
        columns.update(frames.channels.columns())
    columns.update(counter=frames.counter, latency_us=frames.latency_us)
    return columns, source


def summary(capture: DecodedCapture, source: str, options: DecodeOptions, temp_source: str) -> dict:
    """The figures printed and written with ``--json`` (lists of three per axis)."""
    frames = capture.frames
    channels = frames.channels
    statuses = {"gyro": frames.status}
    if channels is not None:
        for name, values in (("accelerometer", channels.acc_status), ("inclinometer", channels.incl_status),
                             ("gyro_temperature", channels.gyro_temp_status),
                             ("accelerometer_temperature", channels.acc_temp_status),
                             ("inclinometer_temperature", channels.incl_temp_status)):
            if values is not None:
                statuses[name] = values
    any_flag = np.zeros(len(frames), bool)
    for values in statuses.values():
        any_flag |= values != 0
    acc = None if channels is None else channels.acc_g
    incl = None if channels is None else channels.incl_g
    out = {
        "file": source,
        "datagram_id": f"0x{capture.datagram_id:02X}",
        "datagram": capture.datagram_label,
        "crlf": capture.crlf,
        "bytes": capture.bytes_total,
        "frames_valid": len(frames),
        "crc_errors": capture.crc_errors,
        "garbage_bytes": capture.garbage_bytes,
        "incomplete_tail_bytes": capture.tail_bytes,
        "lost_frames": frames.lost_frames,
        "status_flagged": int(any_flag.sum()),
        "status_flagged_by_sensor": {k: int(np.count_nonzero(v)) for k, v in statuses.items()},
        "counter_step": capture.counter_step,
        "sample_rate_hz": capture.sample_rate_hz,
        "duration_s": (len(frames) + frames.lost_frames
                       + sum(s.replaced_frames or 0 for s in capture.specials)) / capture.sample_rate_hz,
        "means_over": "datagrams whose own sensor's status byte is 0 (all datagrams if none)",
        "gyro_mean_dps": _mean(frames.rate, frames.status),
        "accelerometer_range_g": options.accelerometer_range_g if acc is not None else None,
        "accelerometer_mean_g": None if acc is None else _mean(acc, channels.acc_status),
        "inclinometer_mean_g": None if incl is None else _mean(incl, channels.incl_status),
        "chamber_temp_c_source": temp_source,
    }
    if frames.temp_c is not None:
        out["gyro_temperature_mean_c"] = _mean(frames.temp_c, frames.temp_status)
    if acc is not None:
        out.update(_gravity_check(acc, channels.acc_status, options.accelerometer_range_g))
    return out


def _mean(values: np.ndarray, status: np.ndarray | None) -> list[float]:
    good = np.ones(len(values), bool) if status is None else np.asarray(status) == 0
    chosen = values[good] if good.any() else values
    return [round(float(v), 9) for v in np.mean(chosen, axis=0)]


def _gravity_check(acc: np.ndarray, status: np.ndarray | None, range_g: int) -> dict:
    """Median |a|: about 1 g for a unit near rest; far from it, the declared range is suspect."""
    good = np.ones(len(acc), bool) if status is None else np.asarray(status) == 0
    magnitude = float(np.median(np.linalg.norm(acc[good] if good.any() else acc, axis=1)))
    out: dict = {"accelerometer_magnitude_median_g": round(magnitude, 6)}
    low, high = _GRAVITY_BAND_G
    if not low <= magnitude <= high:
        out["accelerometer_note"] = (
            f"median |a| is {magnitude:.3f} g at the ±{range_g} g range's LSB; a unit near rest "
            "feels 1 g, so the capture's range is probably another one (--accelerometer-range-g)")
    return out


def _configuration_figures(specials: list[SpecialInCapture], capture: DecodedCapture) -> dict:
    """The unit's first configuration datagram (0xBC/0xBD), when the capture holds one, against the stream."""
    config = next((s.found.value for s in specials if isinstance(s.found.value, UnitConfiguration)), None)
    if config is None:
        return {}
    out: dict = {"unit_configuration": configuration_fields(config)}
    if config.datagram != capture.datagram_id or (
            config.sample_rate_hz is not None and config.sample_rate_hz != capture.sample_rate_hz):
        out["configuration_note"] = (
            f"the configuration datagram says 0x{config.datagram:02X} at {config.sample_rate_hz} Hz; "
            f"the stream is 0x{capture.datagram_id:02X} at {capture.sample_rate_hz:g} Hz")
    return out


def write_log(columns: dict[str, np.ndarray], out: Path) -> None:
    table = pa.table({name: pa.array(np.asarray(values)) for name, values in columns.items()})
    suffix = out.suffix.lower()
    if suffix in (".parquet", ".pq"):

        pq.write_table(table, out, compression="zstd")
    elif suffix == ".csv":

        pacsv.write_csv(table, out)
    else:
        raise BadInput(f"--out {out}: unknown log format {out.suffix!r}; use .parquet or .csv")


def cmd_decode(args: argparse.Namespace) -> int:
    if args.driver not in DRIVERS:
        raise BadInput(f"--driver {args.driver}: known drivers: {', '.join(DRIVERS)}")
    options = DecodeOptions(accelerometer_range_g=args.accelerometer_range_g,
                            rate_lsb=args.rate_lsb, axis=args.axis,
                            table_rate_dps=args.table_rate_dps, chamber_temp_c=args.chamber_temp_c)
    for name, value in (("--rate-lsb", options.rate_lsb), ("--table-rate-dps", options.table_rate_dps),
                        ("--chamber-temp-c", options.chamber_temp_c)):
        if value is not None and not math.isfinite(value):
            raise BadInput(f"{name}: {value!r} is not a finite number")
    if not options.rate_lsb > 0:
        raise BadInput(f"--rate-lsb: must be > 0, got {options.rate_lsb!r}")
    source = str(args.capture)
    data = read_capture(args.capture)
    capture = decode_capture(data, source, options)
    columns, temp_source = log_columns(capture, options)
    figures = summary(capture, source, options, temp_source)
    figures.update(special_figures(capture.specials))
    figures.update(_configuration_figures(capture.specials, capture))
    if args.out:
        _writing("--out", args.out, lambda: write_log(columns, Path(args.out)))
        figures["log"] = str(args.out)
    _print(figures)
    for special in capture.specials:
        print(f"  special datagram at {describe_special(special)}")
    if args.json:
        _writing("--json", args.json, lambda: Path(args.json).write_text(
            json.dumps(figures, indent=2) + "\n", encoding="utf-8"))
    return EXIT_OK


def _writing(option: str, path: str, write) -> None:
    """An output that cannot be written is bad input naming the option and the file."""
    try:
        write()
    except OSError as exc:
        raise BadInput(f"{option} {path}: cannot write: {exc.strerror or exc}") from None


def _print(figures: dict) -> None:
    print(f"{figures['file']}: datagram {figures['datagram']}"
          f"{' with CR LF' if figures['crlf'] else ''}, {figures['sample_rate_hz']:g} Hz "
          f"(counter step {figures['counter_step']}, TS1524 §7.5.2.2.18)")
    for key in ("frames_valid", "crc_errors", "garbage_bytes", "incomplete_tail_bytes", "lost_frames",
                "replaced_frames", "part_number", "part_number_revision", "serial_number", "status_flagged", "duration_s", "gyro_mean_dps", "accelerometer_range_g",
                "accelerometer_mean_g", "accelerometer_magnitude_median_g", "inclinometer_mean_g",
                "gyro_temperature_mean_c", "accelerometer_note", "unit_configuration",
                "configuration_note", "chamber_temp_c_source", "log"):
        if figures.get(key) is not None:
            print(f"  {key}: {figures[key]}")
