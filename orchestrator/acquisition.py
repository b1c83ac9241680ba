"""Acquisition: a logged step's gyro samples, with chamber and table context, into chunks.

One job, apart from the engine that decides when to log: read the gyro in
blocks, read the table back after each block and the chamber after each
chunk, build the per-sample columns (chamber temperature interpolated between polls, the demanded table
rate, the integrated table angle, all three axes when the gyro gives them)
and write them as journaled Parquet chunks.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from gyrocal.instruments.factory import Instruments
from gyrocal.instruments.gyro.channels import SensorChannels, concat_channels
from gyrocal.instruments.gyro.plausibility import StreamPlausibility
from gyrocal.instruments.interfaces import GyroBlock
from gyrocal.models.clock import RealClock, SimClock
from gyrocal.orchestrator.plan import PlanStep
from gyrocal.orchestrator.progress import Progress
from gyrocal.orchestrator.table_synthesis import Sinusoid
from gyrocal.record.journal import Journal, JournalEvent
from gyrocal.record.run_folder import SAMPLE_FLAG_GYRO_FLAGGED, RunFolder


@dataclass
class StepResult:
    step_id: str
    attempt: int
    samples: int = 0
    lost_frames: int = 0
    crc_errors: int = 0
    chunks: list[str] = field(default_factory=list)
    table_rate_max_dev_dps: float = 0.0
    flagged_samples: int = 0        # the gyro's status byte marks them saturated / in error
    implausible: str | None = None  # why the stream cannot be real (stale, counter jump)

    def count(self, block: GyroBlock) -> None:
        """Add a read block's samples, lost frames, CRC errors and flagged samples."""
        self.samples += len(block)
        self.lost_frames += block.lost_frames
        self.crc_errors += block.crc_errors
        self.flagged_samples += block.flagged_count

    @property
    def bad_fraction(self) -> float:
        """Lost, CRC-failed and flagged frames over all frames of the attempt."""
        frames = self.samples + self.lost_frames + self.crc_errors
        return (self.lost_frames + self.crc_errors + self.flagged_samples) / max(frames, 1)


@dataclass
class AcquisitionPolicy:
    chunk_s: float            # seconds of samples per Parquet chunk
    block_s: float            # seconds of samples per driver read (and per table readback)
    read_timeout_margin_s: float


def _continuing(index: np.ndarray, last_index: int) -> tuple[np.ndarray, int]:
    """A block's frame indices, renumbered after the last one when the counter restarted
    (or wrapped), and the new last index."""
    if last_index >= 0 and len(index) and index[0] <= last_index:
        index = index - index[0] + last_index + 1
    if len(index):
        last_index = int(index[-1])
    return index, last_index


def _no_columns() -> dict[str, list[np.ndarray]]:
    return {"index": [], "gyro": [], "sensor": [], "xyz": [], "raw_status": [], "flagged": []}


@dataclass
class _Pending:
    """The blocks read since the last chunk was written, column by column."""

    columns: dict[str, list[np.ndarray]] = field(default_factory=_no_columns)
    channels: list[SensorChannels] = field(default_factory=list)  # accelerometers, inclinometers, temperatures
    n: int = 0

    def add(self, block: GyroBlock, index: np.ndarray) -> None:
        self.columns["index"].append(index)
        self.columns["gyro"].append(np.asarray(block.rate, dtype=np.float64))
        self.columns["raw_status"].append(np.asarray(block.status, dtype=np.uint8))
        self.columns["flagged"].append(np.zeros(len(block), bool) if block.flagged is None
                                       else np.asarray(block.flagged, dtype=bool))
        if block.rate_xyz is not None:     # all three axes (a multi-axis IMU calibration)
            self.columns["xyz"].append(np.asarray(block.rate_xyz, dtype=np.float64).reshape(-1, 3))
        if block.channels is not None:
            self.channels.append(block.channels)
        temp = block.temperature_c
        self.columns["sensor"].append(np.full(len(block), np.nan) if temp is None
                                      else np.asarray(temp, dtype=np.float64))
        self.n += len(block)


class Acquisition:
    """Records logged steps for the engine (``record``)."""

    def __init__(self, instruments: Instruments, clock: RealClock | SimClock, folder: RunFolder,
                 journal: Journal, progress: Progress, policy: AcquisitionPolicy,
                 poll_chamber: Callable[[], float], elapsed_s: Callable[[], float],
                 on_attempt: Callable[[str, int], None] | None = None) -> None:
        self.inst = instruments
        self.clock = clock
        self.folder = folder
        self.journal = journal
        self.progress = progress
        self.policy = policy
        self.poll_chamber = poll_chamber
        self.elapsed_s = elapsed_s
        #: told (step id, attempt) before an attempt's first sample: a dry run derives its
        #: simulators' random draws from them, so a seed reproduces every sample
        self.on_attempt = on_attempt

    def read_timeout_s(self, block_s: float) -> float:
        """Wall seconds a gyro read of ``block_s`` clock seconds may take before it times out.

        On simulated time the stream runs as fast as it is read, so only the
        margin applies; on (scaled) real time the block itself takes
        ``block_s / speed`` wall seconds.
        """
        wall_s = 0.0 if isinstance(self.clock, SimClock) else block_s / self.clock.speed
        return wall_s + self.policy.read_timeout_margin_s

    def record(self, step: PlanStep, attempt: int, rate_dps: float,
               at_rate_since_wall_s: float | None = None,
               reference: Sinusoid | None = None,
               draw_attempt: int | None = None) -> StepResult:
        """Log ``step.duration_s`` of gyro samples with chamber and table context, in chunks.

        ``at_rate_since_wall_s``: when the table was confirmed at ``rate_dps``
        (monotonic wall time); on a real clock, frames the gyro's counter shows
        were sampled before it make the attempt implausible (stale data).
        ``reference``: the sinusoid the table turns (a frequency-response step); it is
        the logged table rate, and each readback is checked against it at that instant.
        ``draw_attempt``: the attempt whose random streams a dry run draws from (the engine's
        ``Rehearsal``: an attempt cut by a kill does not count); default ``attempt``.
        """
        fs = self.inst.sample_rate_hz
        n_total = int(round(step.duration_s * fs))
        chunk_n = max(1, int(self.policy.chunk_s * fs))
        block_n = max(1, min(chunk_n, int(self.policy.block_s * fs)))
        result = StepResult(step.step_id, attempt)
        gyro = self.inst.gyro
        if self.on_attempt is not None:
            self.on_attempt(step.step_id, attempt if draw_attempt is None else draw_attempt)
        gyro.flush()
        plausible = self._plausibility(step, fs, at_rate_since_wall_s)
        t0 = self.clock.now_s()
        angle_start = (t0, 0.0, self._safe_position())
        context_t, context_chamber = [t0], [self.poll_chamber()]
        def demand_now() -> float:
            return rate_dps if reference is None else float(reference.rate_dps(self.clock.now_s()))

        self._check_table_rate(result, demand_now(), self.inst.table.read_rate_dps())
        angle_start = (t0, demand_now(), angle_start[2])
        pending, chunk_index, last_index = _Pending(), 0, -1
        timeout_s = self.read_timeout_s(block_n / fs)
        want = self._elapse_next(min(block_n, n_total), fs)
        ahead = self.clock.simulated     # see _block_context
        while want > 0:
            chunk_due = pending.n + want >= chunk_n or result.samples + want >= n_total
            chamber_c = self._block_context(result, demand_now, chunk_due) if ahead else None
            following = self._elapse_next(min(block_n, n_total - result.samples - want), fs)
            block = gyro.read_samples(want, timeout_s=timeout_s)
            result.count(block)
            index = np.asarray(block.index, dtype=np.int64)
            if plausible is not None and len(index) and self._implausible(
                    plausible, step, attempt, result, len(block), index):
                return result        # nothing of this attempt is calibration data
            index, last_index = _continuing(index, last_index)
            if not ahead:
                chamber_c = self._block_context(result, demand_now, chunk_due)
            pending.add(block, index)
            want = following
            if chunk_due:
                context_t.append(t0 + (last_index + 1) / fs)
                context_chamber.append(float(chamber_c))    # type: ignore[arg-type]
                angle_start = self._write_chunk(step, attempt, chunk_index, pending, self._assemble(
                    pending.columns, t0, fs, context_t, context_chamber, rate_dps, angle_start,
                    reference), result)
                chunk_index, pending = chunk_index + 1, _Pending()
        return result

    def _elapse_next(self, frames: int, fs: float) -> int:
        """Let the next block's ``frames`` pass (returned), before this block is read.

        On simulated time the gyro's thread then makes the next block's frames while
        this one crosses the pty, is decoded, assembled and written, on the other core;
        the frames depend on the controller's calls alone, not on when they are made,
        and every instrument call of this block was made before (:meth:`_block_context`).
        On a real clock it moves nothing: the unit streams by itself.
        """
        if frames > 0:
            self.clock.elapse_reading(frames / fs)
        return frames

    def _block_context(self, result: StepResult, demand_now: Callable[[], float],
                       chunk_due: bool) -> float | None:
        """The table readback after a block and, at a chunk's end, the chamber poll (returned).

        At the block's end time: on a real clock after the block is read (the readback
        follows the data it vouches for); on simulated time before it is read, once the
        clock stands at the block's end, so the next block's time can pass while this one
        is read (:meth:`_elapse_next`): the same calls at the same clock times either way,
        so the same readbacks, polls and frames. The chamber is polled once a chunk (every
        chunk_s of clock time, on a station as on simulated time), not every block: it is
        soaked within its tolerance while a step is logged and its air changes over
        minutes, so the column interpolated between these polls is as good, and its alarm
        is still seen within a chunk (the limit controller cuts the heaters by itself). At
        every block it made ~16,000 of an overnight dry run's ~35,000 Modbus exchanges.
        """
        reading = self.inst.table.read_rate_dps()
        self._check_table_rate(result, demand_now(), reading)
        self.progress.update(table_dps=reading, elapsed_s=self.elapsed_s())
        return self.poll_chamber() if chunk_due else None

    def _plausibility(self, step: PlanStep, fs: float,
                      at_rate_since_wall_s: float | None) -> StreamPlausibility | None:
        """On a real clock the stream is checked against wall time (instruments/gyro/
        plausibility.py): n samples cannot come faster than the unit makes them."""
        if isinstance(self.clock, SimClock):
            return None
        plausible = StreamPlausibility(fs, speed=self.clock.speed)
        flushed = time.monotonic()
        plausible.start(flushed, since_wall_s=self._frames_since(
            step, flushed, at_rate_since_wall_s, plausible.slack_s))
        return plausible

    def _implausible(self, plausible: StreamPlausibility, step: PlanStep, attempt: int,
                     result: StepResult, rows: int, index: np.ndarray) -> bool:
        """Check a block against wall time; an impossible stream is journaled and ends the attempt."""
        verdict = plausible.check(time.monotonic(), rows, int(index[0]), int(index[-1]))
        if verdict is None:
            return False
        result.implausible = verdict.reason
        self.journal.append(JournalEvent.GYRO_IMPLAUSIBLE, step_id=step.step_id,
                            attempt=attempt, reason=verdict.reason,
                            samples=verdict.samples, frame_span=verdict.frame_span,
                            allowed_frames=round(verdict.allowed_frames, 1),
                            wall_s=round(verdict.wall_s, 4))
        return True

    def _write_chunk(self, step: PlanStep, attempt: int, chunk_index: int, pending: _Pending,
                     columns: dict[str, np.ndarray], result: StepResult
                     ) -> tuple[float, float, float]:
        """Write one chunk (with the sensor channels when every row has them) and journal it;
        returns where the table angle continues: (t_s, rate_dps, angle_deg) of its last row."""
        if pending.channels and sum(c.rows for c in pending.channels) == pending.n:
            columns.update(concat_channels(pending.channels).columns())
        record = self.folder.write_chunk(step.step_id, attempt, chunk_index, columns)
        self.journal.append(JournalEvent.CHUNK_WRITTEN, step_id=step.step_id, attempt=attempt,
                            path=record.path, sha256=record.sha256, rows=record.rows)
        result.chunks.append(record.path)
        return (float(columns["t_s"][-1]), float(columns["table_rate_dps"][-1]),
                float(columns["table_angle_deg"][-1]))

    def _frames_since(self, step: PlanStep, flushed_wall_s: float,
                      at_rate_since_wall_s: float | None, slack_s: float) -> float | None:
        """Earliest wall time a frame of this step may have been sampled at.

        After the table's confirming readback (frames before it may be from its
        acceleration), and at most the step's settle (plus the in-flight slack)
        before the flush: a table long at its rate does not license frames a
        minute old (a replayed buffer).
        """
        if at_rate_since_wall_s is None or isinstance(self.clock, SimClock):
            return None
        lookback_s = step.settle_s / self.clock.speed + slack_s
        return max(at_rate_since_wall_s, flushed_wall_s - lookback_s)

    def _safe_position(self) -> float:
        return float(self.inst.table.read_position_deg())

    def _check_table_rate(self, result: StepResult, demand_dps: float, reading_dps: float) -> None:
        """Track how far the table's rate readback strays from the demand during a logged step."""
        deviation = abs(reading_dps - demand_dps)
        result.table_rate_max_dev_dps = max(result.table_rate_max_dev_dps, deviation)

    @staticmethod
    def _assemble(pending: dict[str, list[np.ndarray]], t0: float, fs: float,
                  context_t: list[float], context_chamber: list[float],
                  rate_dps: float, angle_start: tuple[float, float, float],
                  reference: Sinusoid | None = None) -> dict[str, np.ndarray]:
        """Per-sample columns: chamber temperature interpolated between polls, table rate.

        The logged table rate is the demanded rate. In rate mode the table
        holds its demand to encoder precision, while its rate *readback* is a
        noisy single-shot estimate (±0.001 deg/s is 3.6 deg/h, more than the
        bias being calibrated); the readbacks are kept as a check instead
        (``table_rate_max_dev_dps`` per step; beyond the rate band the step is
        bad and repeated). The table angle is the angle read at the start of
        the step plus the integral of that rate: a position readback modulo
        360° cannot be unwrapped between polls at high rates, the integral can.
        """
        index = np.concatenate(pending["index"])
        t_s = t0 + index / fs
        chamber = np.interp(t_s, context_t, context_chamber)
        rate = (np.full(t_s.shape, float(rate_dps)) if reference is None
                else np.asarray(reference.rate_dps(t_s), dtype=float))
        angle = integrate_angle(rate, t_s, angle_start)
        columns = {
            "t_s": t_s,
            "table_rate_dps": rate,
            "chamber_temp_c": chamber,
            "gyro": np.concatenate(pending["gyro"]),
            "sensor_temp_c": np.concatenate(pending["sensor"]),
            "table_angle_deg": angle,
        }
        # per sample: the gyro's raw status byte, and the record's own status bits (0 = good;
        # SAMPLE_FLAG_GYRO_FLAGGED: the unit marks the sample saturated or in error)
        columns["gyro_status"] = np.concatenate(pending["raw_status"])
        columns["status"] = np.where(np.concatenate(pending["flagged"]),
                                     SAMPLE_FLAG_GYRO_FLAGGED, 0).astype(np.uint8)
        xyz = pending.get("xyz") or []
        if sum(len(x) for x in xyz) == len(t_s):
            stacked = np.concatenate(xyz)
            columns.update(gyro_x=stacked[:, 0], gyro_y=stacked[:, 1], gyro_z=stacked[:, 2])
        return columns


def integrate_angle(rate_dps: np.ndarray, t_s: np.ndarray, start: tuple[float, float, float]
                    ) -> np.ndarray:
    """Trapezoidal integral of rate continuing from ``start = (t_s, rate_dps, angle_deg)``."""
    if len(t_s) == 0:
        return np.empty(0)
    t_prev, rate_prev, angle_prev = start
    dt = np.diff(np.concatenate(([t_prev], t_s)))
    prev = np.concatenate(([rate_prev], rate_dps[:-1]))
    return angle_prev + np.cumsum(0.5 * (rate_dps + prev) * dt)
