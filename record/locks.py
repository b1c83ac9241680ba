"""One controller per run folder and per instrument: OS file locks with a holder record.

Two controllers on one rig are worse than none: their commands interleave (one
``stop`` halts the other's table) and their journal lines interleave until the
hash chain breaks. So a controller takes, for its whole life, an exclusive
``fcntl.flock`` on

* the run folder (``RUN_DIR/controller.lock``): run, resume and a report
  rebuild take it, so none of them runs while another writes the folder;
* every instrument of the station (one file per key in the lock directory:
  ``$GYROCAL_LOCK_DIR``, else ``$XDG_RUNTIME_DIR/gyrocal-locks``, else
  ``/tmp/gyrocal-locks``), so two runs on one station cannot both drive it. The
  keys are what an address *reaches*, not how it is spelled
  (``instrument_address.py``: resolved host and port, a device's real path),
  and, once connected, the serial the chamber and the table report.

The kernel drops an ``flock`` when its process ends however it ends (kill -9,
power loss takes the whole machine), so a crashed controller never leaves a
lock that blocks the next one. The JSON holder record (pid, host, start time,
command) written into the locked file is what a refused controller prints, and
a record found in a lock that was free is a *stale* record: the previous
holder ended without releasing (a crash); the caller journals it.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import re
import socket
import sys
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path

from gyrocal.instruments.address import instrument_keys
from gyrocal.instruments.identity import reported_serial
from gyrocal.instruments.interfaces import Identity

RUN_LOCK_FILE = "controller.lock"
LOCK_DIR_ENV = "GYROCAL_LOCK_DIR"


class LockBusyError(Exception):
    """Another live controller holds the lock (exit 3: nothing was commanded)."""

    def __init__(self, what: str, holder: LockHolder | None) -> None:
        self.what = what
        self.holder = holder
        who = holder.describe() if holder is not None else "another process (no holder record)"
        super().__init__(f"{what} is in use by {who}; refusing to start a second controller")


@dataclass(frozen=True)
class LockHolder:
    """Who holds a lock: enough to find the process (or to know it is gone)."""

    pid: int
    host: str
    started_utc: str
    command: str

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host} since {self.started_utc} ({self.command})"

    @staticmethod
    def me() -> LockHolder:
        return LockHolder(
            pid=os.getpid(),
            host=socket.gethostname(),
            started_utc=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            command=" ".join(["gyrocal", *sys.argv[1:]])[:300],
        )


def _parse_holder(text: str) -> LockHolder | None:
    try:
        data = json.loads(text)
        return LockHolder(pid=int(data["pid"]), host=str(data["host"]),
                          started_utc=str(data["started_utc"]), command=str(data["command"]))
    except (ValueError, KeyError, TypeError):
        return None


def _read_record(fd: int) -> LockHolder | None:
    os.lseek(fd, 0, os.SEEK_SET)
    return _parse_holder(os.read(fd, 4096).decode("utf-8", "replace"))


class FileLock:
    """An exclusive flock on ``path`` holding a JSON :class:`LockHolder` record."""

    def __init__(self, path: Path, what: str, create_dir: bool = False) -> None:
        self.path = Path(path)
        self.what = what
        self.create_dir = create_dir
        self.stale: LockHolder | None = None   # record left by a holder that crashed
        self._fd: int | None = None

    def acquire(self) -> FileLock:
        if self.create_dir:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        elif not self.path.parent.is_dir():
            raise FileNotFoundError(f"{self.path.parent}: no such folder")
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_record(fd)
            os.close(fd)
            raise LockBusyError(self.what, holder) from None
        self.stale = _read_record(fd)
        record = json.dumps(asdict(LockHolder.me())).encode()
        os.ftruncate(fd, 0)
        os.pwrite(fd, record, 0)
        os.fsync(fd)
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)    # an empty record: released cleanly, nothing stale
        os.close(fd)               # closing drops the flock

    def __enter__(self) -> FileLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def holder(path: str | os.PathLike[str]) -> LockHolder | None:
    """Who holds the lock of a run folder (or a lock file), or None when it is free.

    For ``gyrocal status``: a probe with a shared lock, never blocking, never
    writing. A record in a free lock is stale and not a holder.
    """
    target = Path(path)
    if target.is_dir():
        target = target / RUN_LOCK_FILE
    try:
        fd = os.open(target, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_record(fd) or LockHolder(pid=0, host="?", started_utc="?", command="?")
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def run_folder_lock(run_dir: str | os.PathLike[str]) -> FileLock:
    return FileLock(Path(run_dir) / RUN_LOCK_FILE, f"run folder {run_dir}")


def lock_dir() -> Path:
    explicit = os.environ.get(LOCK_DIR_ENV)
    if explicit:
        return Path(explicit)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and Path(runtime).is_dir():
        return Path(runtime) / "gyrocal-locks"
    return Path("/tmp/gyrocal-locks")


def address_lock_path(address: str) -> Path:
    """One file per instrument key; readable name plus a hash (keys hold ``/`` and ``:``)."""
    readable = re.sub(r"[^A-Za-z0-9._-]+", "_", address.strip())[:60]
    digest = hashlib.sha256(address.strip().encode()).hexdigest()[:12]
    return lock_dir() / f"{readable}-{digest}.lock"


@contextlib.contextmanager
def instrument_locks(addresses: dict[str, str]) -> Iterator[list[FileLock]]:
    """Exclusive locks on every instrument ``role -> address`` reaches, for the life of the block.

    Keyed on what the address *reaches* (``instrument_address.instrument_keys``:
    the host resolved to its IP addresses with the port, a device's real path),
    never on its spelling, so ``localhost:5020`` and ``127.0.0.1:5020`` are one
    lock. Taken in sorted order (no deadlock between two controllers). An
    address that cannot be resolved is a station-file error (``AddressError``).
    """
    keyed: dict[str, list[str]] = {}
    for role, address in addresses.items():
        for key in instrument_keys(role, address):
            keyed.setdefault(key, []).append(f"{role} at {address}")
    with _held(sorted(keyed.items())) as held:
        yield held


@contextlib.contextmanager
def identity_locks(identities: list[Identity]) -> Iterator[list[FileLock]]:
    """Exclusive locks on the serials the connected instruments reported (driver + serial).

    The second key of an instrument: two addresses that resolve differently but
    reach one controller (a serial gateway and its TCP port, two NICs) still
    meet here, before preflight commands anything. An instrument that reports
    no serial is keyed by its address alone.
    """
    serials = {ident: reported_serial(ident.description) for ident in identities}
    keyed = {f"serial:{ident.driver}:{serial.strip().upper()}": [f"{ident.role} serial {serial}"]
             for ident, serial in serials.items() if serial and serial.strip()}
    with _held(sorted(keyed.items())) as held:
        yield held


@contextlib.contextmanager
def _held(keyed: list[tuple[str, list[str]]]) -> Iterator[list[FileLock]]:
    held: list[FileLock] = []
    try:
        for key, names in keyed:
            what = f"{' and '.join(dict.fromkeys(names))} ({key})"
            held.append(FileLock(address_lock_path(key), what, create_dir=True).acquire())
        yield held
    finally:
        for lock in reversed(held):
            lock.release()
