"""The station's Ed25519 key: what makes a run folder's history authentic, not just consistent.

A hash chain proves that the journal's lines follow from each other, but
anyone who can write the folder can edit a line and recompute every hash
after it. A signature over the chain head with a key the editor does not
hold closes that gap: the station keeps the private key (readable only by the
operator account), every writer of a run folder ends its session with a
``sealed`` journal event carrying the signature over the head, and
``gyrocal verify RUN_DIR --key station.pub`` checks it against the public key
QA trusts. Each seal is also recorded in the station ledger beside the key
(:mod:`gyrocal.record.ledger`), so a deleted or replaced run is noticed. The cryptography is the ``cryptography`` package's Ed25519 — no
hand-written primitives.

What a signature cannot do: someone holding the private key can forge a
whole history. That is why the private key lives with the station, not in the
run folder, and why the public key to check against comes from QA's records,
not from the folder (the seal embeds its public key only so that a consistent
but re-signed history can be told apart from an intact one by fingerprint).
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from gyrocal.errors import BadInput
from gyrocal.record.journal import JournalEvent
from gyrocal.record.ledger import append_entry, ledger_path_for

#: The journal event that signs the chain head; always the last line a writer leaves.
SEAL_EVENT = JournalEvent.SEALED
#: The fields of a seal covered by its signature (everything but the signature itself).
SIGNED_FIELDS = ("seq", "wall_time", "event", "prev_sha256", "run_id", "reason",
                 "key_fingerprint", "public_key")
#: Environment variable naming the private key, when the station file names none.
KEY_ENV = "GYROCAL_SIGNING_KEY"


class SigningKeyError(BadInput):
    """A key file that cannot be used (names the file and why)."""


def fingerprint(public_key: Ed25519PublicKey) -> str:
    """``SHA256:`` + base64 of the SHA-256 of the raw 32-byte key, as ssh-keygen prints it."""
    raw = public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    digest = hashlib.sha256(raw).digest()
    return "SHA256:" + base64.b64encode(digest).decode().rstrip("=")


def _raw_public(public_key: Ed25519PublicKey) -> str:
    raw = public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return base64.b64encode(raw).decode()


@dataclass(frozen=True)
class KeyPairFiles:
    private: Path
    public: Path
    fingerprint: str


def generate_key_pair(folder: Path, name: str = "station") -> KeyPairFiles:
    """Write ``NAME.key`` (PKCS#8 PEM, mode 0600) and ``NAME.pub`` (PEM) into ``folder``.

    Refuses to overwrite an existing private key: replacing a station key
    silently would orphan every run signed with it.
    """
    folder.mkdir(parents=True, exist_ok=True)
    private_path, public_path = folder / f"{name}.key", folder / f"{name}.pub"
    if private_path.exists():
        raise SigningKeyError(f"{private_path}: exists; a station key is never overwritten "
                        "(move it away first if you really mean to replace it)")
    key = Ed25519PrivateKey.generate()
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                            serialization.NoEncryption())
    descriptor = os.open(private_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "wb") as handle:
        handle.write(pem)
    public_path.write_bytes(key.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo))
    return KeyPairFiles(private_path, public_path, fingerprint(key.public_key()))


def load_private_key(path: Path) -> Ed25519PrivateKey:
    """The station's private key; refuses a file others can read (the signature means nothing then)."""
    if not path.is_file():
        raise SigningKeyError(f"{path}: signing key not found")
    mode = path.stat().st_mode & 0o077
    if mode:
        raise SigningKeyError(f"{path}: signing key is readable by others (mode "
                        f"{path.stat().st_mode & 0o777:o}); chmod 600 it")
    try:
        key = serialization.load_pem_private_key(path.read_bytes(), password=None)
    except (ValueError, TypeError) as exc:
        raise SigningKeyError(f"{path}: not a PEM private key: {exc}") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise SigningKeyError(f"{path}: not an Ed25519 key")
    return key


def load_public_key(path: Path) -> Ed25519PublicKey:
    if not path.is_file():
        raise SigningKeyError(f"{path}: public key not found")
    try:
        key = serialization.load_pem_public_key(path.read_bytes())
    except (ValueError, TypeError) as exc:
        raise SigningKeyError(f"{path}: not a PEM public key: {exc}") from None
    if not isinstance(key, Ed25519PublicKey):
        raise SigningKeyError(f"{path}: not an Ed25519 public key")
    return key


def signed_bytes(event: dict[str, Any]) -> bytes:
    """The canonical bytes a seal's signature covers."""
    payload = {name: event.get(name) for name in SIGNED_FIELDS}
    return json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()


#: What a report's signature covers: the run, the chain head when the report was
#: built (the line the following ``report_written`` event chains to) and the SHA-256
#: of results.json without its ``signature`` field — so the report alone is signed.
REPORT_SIGNED_FIELDS = ("run_id", "chain_head", "results_sha256", "key_fingerprint",
                        "public_key")


def report_signed_bytes(signature: dict[str, Any]) -> bytes:
    payload = {"purpose": "gyrocal report", **{n: signature.get(n) for n in REPORT_SIGNED_FIELDS}}
    return json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()


class Signer:
    """Seals a journal: appends a ``sealed`` event signing the current chain head."""

    def __init__(self, key: Ed25519PrivateKey, source: str, ledger: Path | None = None) -> None:
        self._key = key
        self.source = source
        #: the station ledger every seal is also recorded in (record/ledger.py)
        self.ledger = ledger
        self.fingerprint = fingerprint(key.public_key())
        self._public = _raw_public(key.public_key())

    def seal(self, journal: Any, run_id: str, reason: str) -> dict[str, Any]:
        """Append the seal through ``journal.append_signed`` (the journal fills seq and head)."""
        def sign(event: dict[str, Any]) -> str:
            return base64.b64encode(self._key.sign(signed_bytes(event))).decode()

        seal = journal.append_signed(SEAL_EVENT, sign, run_id=run_id, reason=reason,
                                     key_fingerprint=self.fingerprint, public_key=self._public)
        if self.ledger is not None:
            append_entry(self.ledger, journal.path.parent, seal, journal.last_sha256)
        return seal

    def sign_report(self, run_id: str, chain_head: str, results_sha256: str) -> dict[str, Any]:
        """The report's own signature block (results.json ``signature``, shown in the HTML)."""
        block: dict[str, Any] = {"run_id": run_id, "chain_head": chain_head,
                                 "results_sha256": results_sha256,
                                 "key_fingerprint": self.fingerprint, "public_key": self._public}
        block["signature"] = base64.b64encode(self._key.sign(report_signed_bytes(block))).decode()
        return block


def seal_signature_valid(event: dict[str, Any], public_key: Ed25519PublicKey | None = None
                         ) -> bool:
    """Whether the seal's signature verifies, with ``public_key`` or the key the seal embeds."""
    return _valid(event, signed_bytes(event), public_key)


def report_signature_valid(block: dict[str, Any], public_key: Ed25519PublicKey | None = None
                           ) -> bool:
    """Whether a report's signature block verifies (``public_key`` or the one it embeds)."""
    return _valid(block, report_signed_bytes(block), public_key)


def _valid(signed: dict[str, Any], message: bytes, public_key: Ed25519PublicKey | None) -> bool:
    try:
        if public_key is None:
            raw = base64.b64decode(str(signed.get("public_key", "")), validate=True)
            public_key = Ed25519PublicKey.from_public_bytes(raw)
        signature = base64.b64decode(str(signed.get("signature", "")), validate=True)
        public_key.verify(signature, message)
        return True
    except (InvalidSignature, ValueError, TypeError):
        return False


def signer_from(path: str | Path | None) -> Signer | None:
    """The signer for a run: the given key file, else ``$GYROCAL_SIGNING_KEY``, else none."""
    chosen = path if path is not None else os.environ.get(KEY_ENV) or None
    if chosen is None:
        return None
    key_path = Path(chosen)
    return Signer(load_private_key(key_path), str(key_path), ledger_path_for(key_path))
