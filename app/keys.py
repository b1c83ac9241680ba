"""Which key seals a run or a rebuilt report, and ``gyrocal keys`` that makes one.

The order is one rule for every command: ``--signing-key``, else
``$GYROCAL_SIGNING_KEY``, else the station file's ``signing_key``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrocal.errors import EXIT_OK
from gyrocal.orchestrator.station import load_station
from gyrocal.problems import ProcedureError
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.signing import (
    KeyPairFiles,
    Signer,
    fingerprint,
    generate_key_pair,
    load_public_key,
    signer_from,
)


def run_signer(cli_key: str | None, station_key: Path | None) -> Signer | None:
    """The key that seals this run: --signing-key, else $GYROCAL_SIGNING_KEY, else the station's."""
    if cli_key is not None:
        return signer_from(cli_key)
    from_env = signer_from(None)
    if from_env is not None:
        return from_env
    return signer_from(station_key) if station_key is not None else None


def report_signer(run_dir: Path, cli_key: str | None) -> Signer | None:
    """The key that seals a rebuilt report: as for run, with the run's own station file."""
    station_key = None
    try:
        source = RunFolder.open(run_dir).read_manifest()["inputs"]["station"]["source"]
        station_key = load_station(source).signing_key
    except (KeyError, OSError, ValueError, ProcedureError):
        station_key = None  # no usable station file: only --signing-key or the env var
    return run_signer(cli_key, station_key)


def cmd_keys(args: argparse.Namespace) -> int:
    """``gyrocal keys``: the station's Ed25519 pair; the private half readable by its owner only."""
    pair = generate_key_pair(Path(args.out), args.name)
    print(f"private key: {pair.private} (mode 600: keep it on the station, never in a run "
          "folder)")
    print(f"public key:  {pair.public} (give it to QA: gyrocal verify RUN_DIR --key "
          f"{pair.public})")
    print(f"fingerprint: {pair.fingerprint}")
    print(f"use it: station file `signing_key: {pair.private}` or "
          f"GYROCAL_SIGNING_KEY={pair.private}")
    return EXIT_OK


def demo_keys(folder: Path) -> KeyPairFiles:
    """The demo's key pair: made on the first demo into this folder, reused after."""
    private, public = folder / "station.key", folder / "station.pub"
    if private.exists() and public.exists():
        return KeyPairFiles(private, public, fingerprint(load_public_key(public)))
    return generate_key_pair(folder)
