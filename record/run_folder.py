"""The run folder: manifest, journal, sample chunks written (see interfaces.md, "Run folder").

Everything an auditor needs to re-derive the report lives here: copies of the
procedure and station as they were run (with SHA-256), the hash-chained
journal, and the gyro samples in Parquet chunks whose hashes the journal
records. Chunks are written atomically, so a crash loses at most the chunk
being written; the journal says which chunks belong to which completed step.
Chunks are read back through ``samples.py`` (the one reader of run chunks).
"""

from __future__ import annotations

import hashlib
import json
import shutil
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from gyrocal import __version__
from gyrocal.errors import BadInput
from gyrocal.instruments.gyro.channels import CHANNEL_COLUMNS, CHANNEL_STATUS_COLUMNS
from gyrocal.instruments.identity import reported_serial
from gyrocal.record.atomic import write_atomic, write_bytes_atomic
from gyrocal.record.journal import Journal, JournalEvent, read_journal, sha256_file

MANIFEST = "manifest.json"
JOURNAL = "journal.jsonl"
SAMPLES = "samples"

#: Columns of every sample chunk; names and units follow gyro-model.md "Measured log".
SAMPLE_COLUMNS = (
    "t_s",
    "table_rate_dps",
    "chamber_temp_c",
    "gyro",
    "sensor_temp_c",
    "table_angle_deg",
)

#: Columns a chunk carries when the gyro gives them (older chunks lack them):
#: the three axes of a multi-axis unit (``gyro`` is the unit under test's axis),
#: the raw status byte, and ``status``, a bit set of :data:`SAMPLE_FLAGS` (0 = good).
OPTIONAL_SAMPLE_COLUMNS = ("gyro_x", "gyro_y", "gyro_z", "gyro_status", "status")
#: What else the gyro's datagram carries, written when present (instruments/gyro/channels.py):
#: accelerometers and inclinometers (``acc_x_g``…, ``incl_x_g``…), per-sensor temperatures
#: (``gyro_temp_x_c``…) and each cluster's status byte. Not read unless asked for.
SENSOR_COLUMNS = CHANNEL_COLUMNS + CHANNEL_STATUS_COLUMNS
_UINT8_COLUMNS = frozenset(("gyro_status", "status") + CHANNEL_STATUS_COLUMNS)
#: Columns Parquet dictionary-encodes: the few-valued ones (status bytes, a step's table
#: rate). A float column of 15,000 distinct samples gains nothing from a dictionary but its
#: cost; encoding only these halves a chunk's write time (2.5 against 4.8 ms for an
#: overnight chunk, measured) and makes it 30 % smaller. The values are unchanged.
_DICTIONARY_COLUMNS = ["table_rate_dps", *sorted(_UINT8_COLUMNS)]

#: ``status`` bits: the gyro's status byte marks the sample saturated / in error
#: for the unit under test. Analyses use only rows with ``status == 0``.
SAMPLE_FLAG_GYRO_FLAGGED = 0x01
SAMPLE_FLAGS = {"gyro_flagged": SAMPLE_FLAG_GYRO_FLAGGED}


#: Manifest fields that say whose run this is, and when and how fast it ran; journaled in
#: run_started so an edit shows (the report and the certificate read them).
IDENTITY_KEYS = ("run_id", "operator", "unit_under_test", "station_name", "mode", "seed",
                 "software", "started_at", "speed")


def identified_instruments(events: list[dict[str, Any]]) -> dict[str, dict[str, str]]:
    """role → driver, address, description, from the latest ``instrument_identified`` events.

    The journal is where the identities are recorded (and signed); the manifest's
    copy is for readers that do not walk the journal, and verify checks it agrees.
    """
    found: dict[str, dict[str, str]] = {}
    for event in events:
        if event.get("event") == JournalEvent.INSTRUMENT_IDENTIFIED and event.get("role"):
            found[str(event["role"])] = {key: event.get(key)
                                         for key in ("driver", "address", "description")}
    return found


def serials_begun_with(events: list[dict[str, Any]]) -> dict[str, str]:
    """role → the first serial this run's journal recorded for it (``instrument_identified``).

    The unit a run began with, not the latest: a session refused for another unit
    journaled that unit's identity before the refusal, and must not make it the
    run's. An instrument that reported no serial in a session is skipped there.
    """
    found: dict[str, str] = {}
    for event in events:
        if event.get("event") == JournalEvent.INSTRUMENT_IDENTIFIED and event.get("role"):
            serial = reported_serial(event.get("description"))
            if serial:
                found.setdefault(str(event["role"]), serial)
    return found


def _arrow_column(values: np.ndarray, kind: type[np.generic]) -> pa.Array:
    """A NumPy column as an Arrow array over the same buffer (no nulls: NaN stays a value).

    ``pa.array`` on a NumPy array asks pyarrow's pandas shim whether it is a pandas
    categorical, and that imports pandas (and pyarrow.compute, dedenting every compute
    function's docstring) at a run's first chunk: ~0.25 s of a dry run's controller
    thread (``python -X importtime``), for columns that are plain arrays. The Parquet
    bytes are the same either way (benchmarks/check_dry_run_determinism.py's comparison).
    """
    array = np.ascontiguousarray(values, dtype=kind)
    return pa.Array.from_buffers(pa.from_numpy_dtype(array.dtype), len(array),
                                 [None, pa.py_buffer(array)], null_count=0)


class RunFolderError(BadInput):
    """The folder is not a usable run folder (names the file)."""


@dataclass(frozen=True)
class ChunkRecord:
    path: str          # relative to the run folder
    sha256: str
    rows: int


def new_run_id() -> str:
    return time.strftime("%Y%m%dT%H%M%S") + "-" + uuid.uuid4().hex[:6]


class RunFolder:
    """Owns one run folder on disk. Create with :meth:`create`, reopen with :meth:`open`."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.journal: Journal | None = None
        self._durable: bool | None = None

    @property
    def durable(self) -> bool:
        """Whether each journal line and chunk is fsynced as it is written.

        Always for a run on a station: its history must survive a power cut.
        A dry run (``mode: sim``) skips the per-write fsyncs (thousands of them
        in a simulated night, seconds of its wall time): every write still
        reaches the kernel before the call returns, so a kill -9 at any point
        loses nothing and leaves the same files (what the crash tests rehearse);
        only a power cut could lose the tail, and the same seed makes it again.
        """
        if self._durable is None:
            self._durable = self.read_manifest().get("mode") != "sim"
        return self._durable

    # -- creation and reopening ------------------------------------------------------------
    @classmethod
    def create(
        cls,
        path: Path,
        procedure_path: Path,
        station_path: Path | None,
        extra_files: dict[str, Path] | None = None,
        manifest_fields: dict[str, Any] | None = None,
    ) -> RunFolder:
        path = Path(path)
        if path.exists() and any(path.iterdir()):
            raise RunFolderError(f"{path}: output folder exists and is not empty; choose another --out")
        path.mkdir(parents=True, exist_ok=True)
        (path / SAMPLES).mkdir()
        folder = cls(path)
        inputs: dict[str, dict[str, str]] = {}
        copies = {"procedure": procedure_path}
        if station_path is not None:
            copies["station"] = station_path
        copies.update(extra_files or {})
        for role, source in copies.items():
            target = path / "inputs" / f"{role}{Path(source).suffix or '.yaml'}"
            target.parent.mkdir(exist_ok=True)
            shutil.copyfile(source, target)
            inputs[role] = {
                "source": str(Path(source).resolve()),
                "copy": str(target.relative_to(path)),
                "sha256": sha256_file(target),
            }
        manifest = {
            "run_id": new_run_id(),
            "software": {"name": "gyrocal", "version": __version__},
            "inputs": inputs,
            "state": "created",
            "started_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "ended_at": None,
            "instruments": {},
        }
        manifest.update(manifest_fields or {})
        folder.write_manifest(manifest)
        return folder

    @classmethod
    def open(cls, path: Path) -> RunFolder:
        path = Path(path)
        if not (path / MANIFEST).is_file():
            raise RunFolderError(f"{path}: not a run folder ({MANIFEST} missing)")
        return cls(path)

    def open_journal(self) -> Journal:
        if self.journal is None:
            self.journal = Journal(self.path / JOURNAL, durable=self.durable)
        return self.journal

    def close(self) -> None:
        if self.journal is not None:
            self.journal.close()
            self.journal = None

    # -- manifest --------------------------------------------------------------------------
    def read_manifest(self) -> dict[str, Any]:
        try:
            return json.loads((self.path / MANIFEST).read_text())
        except json.JSONDecodeError as exc:
            raise RunFolderError(f"{self.path / MANIFEST}: not valid JSON: {exc}") from None

    def write_manifest(self, manifest: dict[str, Any]) -> None:
        data = json.dumps(manifest, indent=2, sort_keys=True, allow_nan=False).encode() + b"\n"
        write_bytes_atomic(self.path / MANIFEST, data)

    def update_manifest(self, **fields: Any) -> dict[str, Any]:
        manifest = self.read_manifest()
        manifest.update(fields)
        self.write_manifest(manifest)
        return manifest

    def input_path(self, role: str) -> Path:
        return self.path / self.read_manifest()["inputs"][role]["copy"]

    # -- samples ---------------------------------------------------------------------------
    def write_chunk(
        self, step_id: str, attempt: int, chunk_index: int, columns: dict[str, np.ndarray]
    ) -> ChunkRecord:
        missing = [name for name in SAMPLE_COLUMNS if name not in columns]
        if missing:
            raise ValueError(f"sample chunk lacks columns {missing}")
        rows = len(columns["t_s"])
        data = {name: _arrow_column(columns[name], np.float64) for name in SAMPLE_COLUMNS}
        for name in OPTIONAL_SAMPLE_COLUMNS + SENSOR_COLUMNS:
            if name in columns:
                kind = np.uint8 if name in _UINT8_COLUMNS else np.float64
                data[name] = _arrow_column(columns[name], kind)
        table = pa.table(data)
        rel = Path(SAMPLES) / step_id / f"attempt{attempt}-chunk{chunk_index:05d}.parquet"
        # Encoded in memory, hashed there and written: hashing the file meant reading it back
        # (an IMU dry run's 750 chunks: ~0.9 s of its controller's time, py-spy)
        buffer = pa.BufferOutputStream()
        pq.write_table(table, buffer, compression="zstd", use_dictionary=_DICTIONARY_COLUMNS)
        data = buffer.getvalue()
        write_atomic(self.path / rel, lambda tmp: tmp.write_bytes(data), durable=self.durable)
        return ChunkRecord(str(rel), hashlib.sha256(data).hexdigest(), rows)

    def journal_events(self) -> list[dict[str, Any]]:
        path = self.path / JOURNAL
        if not path.exists():
            return []
        return [entry.event for entry in read_journal(path)]
