"""The auditor's checklist: every way to edit a finished run folder, and what verify says.

Each case copies a finished, signed run, tampers with it as someone with write
access to the folder could (change, truncate, reorder, append, delete,
re-hash, recompute the hash chain, re-sign with a key of their own), and runs
``gyrocal verify`` with and without the station's public key. Expectation
``"always"``: caught with or without the key. ``"key"``: only a key can catch
it — caught with the key, and without it verify must not claim authenticity.

The chain and seal rewriting below is written from the journal's documented
format (one JSON object a line, sorted keys, ``prev_sha256`` = SHA-256 of the
previous line's bytes, Ed25519 over the seal's fields), not with the
project's journal writer, so the attacker here is independent of our code.
"""

from __future__ import annotations

import base64
import hashlib
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from gyrocal.cli import main
from gyrocal.record.signing import SIGNED_FIELDS, fingerprint, generate_key_pair
from gyrocal.reports.verify import verify_run_folder

pytestmark = pytest.mark.timeout(300)
ROOT = Path(__file__).resolve().parents[2]
GENESIS = "0" * 64


# -- the runs under audit ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    return generate_key_pair(tmp_path_factory.mktemp("station-keys"))


@pytest.fixture(scope="module")
def signed_run(tmp_path_factory, keys) -> Path:
    """A finished smoke run with retries in its history (a transient chamber silence)."""
    out = tmp_path_factory.mktemp("audit") / "run"
    code = main(["run", str(ROOT / "procedures/smoke.yaml"), "--sim", "--out", str(out),
                 "--seed", "3", "--signing-key", str(keys.private),
                 "--inject", "chamber.no_reply:2@T01.static"])
    assert code == 0
    events = _events(out)
    assert any(e["event"] == "retry" for e in events)
    # certified, as QA would receive it: the certificate is part of the signed history
    assert main(["certificate", str(out), "--signing-key", str(keys.private)]) == 0
    assert _events(out)[-2]["event"] == "certificate_written"
    return out


@pytest.fixture(scope="module")
def faulted_then_resumed_run(tmp_path_factory, keys) -> Path:
    """A run that faulted (interlock), was resumed and finished: its history has a fault."""
    out = tmp_path_factory.mktemp("audit-fault") / "run"
    code = main(["run", str(ROOT / "procedures/smoke.yaml"), "--sim", "--out", str(out),
                 "--seed", "4", "--signing-key", str(keys.private),
                 "--inject", "table.interlock_open:always@T02.sf.+10dps"])
    assert code == 3
    assert main(["resume", str(out), "--signing-key", str(keys.private)]) == 0
    assert any(e["event"] == "fault" for e in _events(out))
    return out


# -- an attacker's tools, written from the documented format ----------------------------------

def _journal(run: Path) -> Path:
    return run / "journal.jsonl"


def _events(run: Path) -> list[dict]:
    return [json.loads(line) for line in _journal(run).read_bytes().splitlines()]


def _encode(event: dict) -> bytes:
    return json.dumps(event, sort_keys=True, separators=(",", ":")).encode() + b"\n"


def _write_rechained(run: Path, events: list[dict]) -> None:
    """Renumber and recompute the hash chain, as anyone with write access can."""
    prev, out = GENESIS, b""
    for seq, event in enumerate(events, start=1):
        event = dict(event, seq=seq, prev_sha256=prev)
        raw = _encode(event)
        out += raw
        prev = hashlib.sha256(raw).hexdigest()
    _journal(run).write_bytes(out)


def _resign(run: Path, events: list[dict], key: Ed25519PrivateKey) -> None:
    """Recompute the chain, replace every seal and the report's signature by ones with ``key``."""
    fp = fingerprint(key.public_key())
    raw_public = base64.b64encode(key.public_key().public_bytes_raw()).decode()
    prev, out = GENESIS, b""
    for seq, event in enumerate(events, start=1):
        event = dict(event, seq=seq, prev_sha256=prev)
        if event["event"] == "run_started":
            event["signing_key"] = fp
        if event["event"] == "report_written":
            event["files"] = _resign_report(run, key, event["files"], events[0]["run_id"], prev)
        if event["event"] == "sealed":
            event.update(key_fingerprint=fp, public_key=raw_public)
            payload = json.dumps({k: event.get(k) for k in SIGNED_FIELDS}, sort_keys=True,
                                 separators=(",", ":")).encode()
            event["signature"] = base64.b64encode(key.sign(payload)).decode()
        raw = _encode(event)
        out += raw
        prev = hashlib.sha256(raw).hexdigest()
    _journal(run).write_bytes(out)


def _resign_report(run: Path, key: Ed25519PrivateKey, files: dict, run_id: str,
                   head: str) -> dict:
    """Re-sign results.json (its ``signature`` block) and patch the HTML to match."""
    path, html_path = run / "report/results.json", run / "report/report.html"
    results = json.loads(path.read_text())
    old = results.pop("signature")
    unsigned = json.dumps(results, indent=2).encode() + b"\n"
    block = {"run_id": run_id, "chain_head": head,
             "results_sha256": hashlib.sha256(unsigned).hexdigest(),
             "key_fingerprint": fingerprint(key.public_key()),
             "public_key": base64.b64encode(key.public_key().public_bytes_raw()).decode()}
    payload = json.dumps({"purpose": "gyrocal report", **block}, sort_keys=True,
                         separators=(",", ":")).encode()
    block["signature"] = base64.b64encode(key.sign(payload)).decode()
    results["signature"] = {"signed": True, **block}
    path.write_bytes(json.dumps(results, indent=2).encode() + b"\n")
    html = html_path.read_text()
    for name in ("key_fingerprint", "chain_head", "results_sha256", "signature"):
        html = html.replace(str(old[name]), str(block[name]))
    html_path.write_text(html)
    return dict(files, **{"report/results.json": _sha(path), "report/report.html": _sha(html_path)})


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _edit_json(path: Path, change: Callable[[dict], None]) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data, indent=2))


def _manifest(run: Path) -> Path:
    return run / "manifest.json"


def _first_chunk(run: Path) -> Path:
    return sorted((run / "samples").rglob("*.parquet"))[0]


def _scale_gyro(path: Path, factor: float) -> None:
    table = pq.read_table(path)
    gyro = table.column("gyro").to_numpy() * factor
    table = table.set_column(table.schema.get_field_index("gyro"), "gyro", pa.array(gyro))
    pq.write_table(table, path)


def _edit_chunk_and_rehash(run: Path, factor: float) -> list[dict]:
    chunk = next(p for p in sorted((run / "samples").rglob("*.parquet")) if "sf.+10dps" in str(p))
    _scale_gyro(chunk, factor)
    events = _events(run)
    rel = str(chunk.relative_to(run))
    for e in events:
        if e["event"] == "chunk_written" and e["path"] == rel:
            e["sha256"] = _sha(chunk)
    return events


ATTACKER = Ed25519PrivateKey.generate()


# -- the cases --------------------------------------------------------------------------------

def t_last_line_deleted(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    _journal(run).write_bytes(b"".join(lines[:-1]))


def t_last_three_lines_deleted(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    _journal(run).write_bytes(b"".join(lines[:-3]))


def t_truncated_to_half_the_lines(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    _journal(run).write_bytes(b"".join(lines[: len(lines) // 2]))


def t_truncated_to_half_the_bytes(run):
    data = _journal(run).read_bytes()
    _journal(run).write_bytes(data[: len(data) // 2])


def t_truncated_to_zero(run):
    _journal(run).write_bytes(b"")


def t_journal_deleted(run):
    _journal(run).unlink()


def t_forged_event_appended_with_valid_chain(run):
    events = _events(run)
    events.append({"event": "step_completed", "step_id": "T03.extra", "attempt": 1,
                   "wall_time": events[-1]["wall_time"] + 1})
    _write_rechained(run, events)


def t_forged_report_event_appended_with_valid_chain(run):
    events = _events(run)
    events.append({"event": "report_written", "files": {}, "wall_time": 1.0})
    _write_rechained(run, events)


def t_forged_event_appended_without_chain(run):
    with open(_journal(run), "ab") as handle:
        handle.write(_encode({"event": "note", "seq": 999, "prev_sha256": "f" * 64}))


def t_two_lines_swapped(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    lines[5], lines[6] = lines[6], lines[5]
    _journal(run).write_bytes(b"".join(lines))


def t_retry_events_stripped_and_rechained(run):
    _write_rechained(run, [e for e in _events(run) if e["event"] != "retry"])


def t_retry_events_stripped_and_resigned(run):
    _resign(run, [e for e in _events(run) if e["event"] != "retry"], ATTACKER)


def t_operator_changed_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m.update(operator="mallory"))


def t_operator_changed_in_manifest_and_journal_rechained(run):
    _edit_json(_manifest(run), lambda m: m.update(operator="mallory"))
    events = _events(run)
    events[0]["identity"]["operator"] = "mallory"
    _write_rechained(run, events)


def t_operator_changed_everywhere_and_resigned(run):
    _edit_json(_manifest(run), lambda m: m.update(operator="mallory"))
    events = _events(run)
    events[0]["identity"]["operator"] = "mallory"
    _resign(run, events, ATTACKER)


def t_run_id_changed_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m.update(run_id="20000101T000000-forged"))


def t_unit_serial_changed_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m["unit_under_test"].update(serial="OTHER-1"))


def t_unit_serial_changed_in_plan(run):
    _edit_json(run / "plan.json", lambda p: p["unit_under_test"].update(serial="OTHER-1"))


def t_unit_serial_changed_in_plan_and_manifest_hash(run):
    _edit_json(run / "plan.json", lambda p: p["unit_under_test"].update(serial="OTHER-1"))
    _edit_json(_manifest(run), lambda m: m.update(plan_sha256=_sha(run / "plan.json")))


def _loosen(plan: dict) -> None:
    for entry in plan["acceptance"]:
        if entry.get("max") is not None:
            entry["max"] = entry["max"] * 1000.0


def t_limits_loosened_plan_rehashed_report_rebuilt(run):
    _edit_json(run / "plan.json", _loosen)
    _edit_json(_manifest(run), lambda m: m.update(plan_sha256=_sha(run / "plan.json")))
    assert main(["report", str(run)]) in (0, 1)


def t_limits_loosened_everywhere_and_resigned(run):
    _edit_json(run / "plan.json", _loosen)
    digest = _sha(run / "plan.json")
    _edit_json(_manifest(run), lambda m: m.update(plan_sha256=digest))
    events = _events(run)
    events[0]["plan_sha256"] = digest
    _resign(run, events, ATTACKER)


def t_results_edited(run):
    _edit_json(run / "report/results.json", lambda r: r["scale_factor_ls"].update(sf=1.0))


def _rewrite_results_and_rechain(run: Path, change: Callable[[dict], None]) -> None:
    path = run / "report/results.json"
    _edit_json(path, change)
    events = _events(run)
    for e in events:
        if e["event"] == "report_written":
            e["files"]["report/results.json"] = _sha(path)
    _write_rechained(run, events)


def t_results_edited_and_report_hash_rechained(run):
    _rewrite_results_and_rechain(run, lambda r: r["scale_factor_ls"].update(sf=1.0))


def t_results_edited_report_hash_rechained_and_resigned(run):
    path = run / "report/results.json"
    _edit_json(path, lambda r: r["scale_factor_ls"].update(sf=1.0))
    events = _events(run)
    for e in events:
        if e["event"] == "report_written":
            e["files"]["report/results.json"] = _sha(path)
    _resign(run, events, ATTACKER)


def t_lines_deleted_then_results_edited(run):
    t_last_three_lines_deleted(run)
    t_results_edited(run)


def t_report_lines_deleted_then_results_edited(run):
    """The report's hash record and all after it dropped, so no hash is left to check."""
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    cut = max(i for i, line in enumerate(lines) if b'"event":"report_written"' in line)
    _journal(run).write_bytes(b"".join(lines[:cut]))
    t_results_edited(run)


def t_sample_chunk_edited(run):
    _scale_gyro(_first_chunk(run), 1.001)


def t_sample_chunk_edited_and_chain_recomputed(run):
    _write_rechained(run, _edit_chunk_and_rehash(run, 1.01))


def t_sample_chunk_edited_chain_recomputed_and_resigned(run):
    _resign(run, _edit_chunk_and_rehash(run, 1.01), ATTACKER)


def t_sample_chunk_deleted(run):
    _first_chunk(run).unlink()


def t_unjournaled_chunk_added(run):
    shutil.copyfile(_first_chunk(run), _first_chunk(run).with_name("attempt9-chunk00000.parquet"))


def t_two_chunks_swapped(run):
    a, b = sorted((run / "samples").rglob("*.parquet"))[1:3]
    data_a, data_b = a.read_bytes(), b.read_bytes()
    a.write_bytes(data_b)
    b.write_bytes(data_a)


def t_input_copy_edited(run):
    path = run / "inputs/procedure.yaml"
    path.write_text(path.read_text() + "\n# edited\n")


def t_input_copy_edited_and_manifest_rehashed(run):
    path = run / "inputs/procedure.yaml"
    path.write_text(path.read_text() + "\n# edited\n")
    _edit_json(_manifest(run), lambda m: m["inputs"]["procedure"].update(sha256=_sha(path)))


def t_plan_deleted(run):
    (run / "plan.json").unlink()


def t_report_html_deleted(run):
    (run / "report/report.html").unlink()


def t_extra_file_in_report(run):
    (run / "report/certificate-forged.html").write_text("<p>PASS</p>")


def t_seal_removed(run):
    t_last_line_deleted(run)


def t_seal_signature_garbled(run):
    events = _events(run)
    events[-1]["signature"] = base64.b64encode(b"\x00" * 64).decode()
    _write_rechained(run, events)


def t_seals_and_key_name_stripped_and_rechained(run):
    events = [e for e in _events(run) if e["event"] != "sealed"]
    events[0].pop("signing_key", None)
    _write_rechained(run, events)


def t_report_signature_stripped_and_rechained(run):
    _rewrite_results_and_rechain(run, lambda r: r.update(signature={"signed": False}))


def t_report_signature_moved_to_another_head_and_rechained(run):
    _rewrite_results_and_rechain(run, lambda r: r["signature"].update(chain_head="0" * 64))


def t_wall_times_shifted_and_rechained(run):
    events = _events(run)
    for e in events:
        e["wall_time"] = e["wall_time"] - 86400.0
    _write_rechained(run, events)


def t_malformed_line(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    lines[10] = b"{this is not json\n"
    _journal(run).write_bytes(b"".join(lines))


def t_binary_garbage_line(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    lines[3] = bytes(range(128, 256)) + b"\n"
    _journal(run).write_bytes(b"".join(lines))


def t_json_array_line(run):
    lines = _journal(run).read_bytes().splitlines(keepends=True)
    lines[2] = b"[1, 2, 3]\n"
    _journal(run).write_bytes(b"".join(lines))


# -- issue 28: what the report, the certificate and status read, and files nobody recorded ----

def t_instrument_identity_changed_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m["instruments"]["table"].update(
        description="ACUTRONIC,ACUTROL3000,REAL-0001,2.0"))


def t_instrument_address_changed_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m["instruments"]["chamber"].update(
        address="socket://10.0.0.7:502"))


def t_start_time_moved_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m.update(started_at="2026-01-02T03:04:05+0000"))


def t_clock_speed_changed_in_manifest(run):
    _edit_json(_manifest(run), lambda m: m.update(speed="1"))


def t_torn_journal_planted(run):
    (run / "journal.torn").write_bytes(b'{"event":"fault","message":"none of this happened"\n')


def t_stray_file_beside_the_journal(run):
    (run / "notes.txt").write_text("calibrated by hand\n")


def t_orphan_planted_without_its_event(run):
    target = run / "orphans" / "samples" / "T01.static" / "attempt1-chunk00000.parquet"
    target.parent.mkdir(parents=True)
    shutil.copyfile(_first_chunk(run), target)


def t_chunk_moved_to_orphans(run):
    chunk = _first_chunk(run)
    target = run / "orphans" / chunk.relative_to(run)
    target.parent.mkdir(parents=True)
    chunk.rename(target)


def t_certificate_pdf_edited(run):
    path = run / "report" / "certificate.pdf"
    path.write_bytes(path.read_bytes().replace(b"SIMULATED", b"CALIBRATE"))


def t_certificate_deleted(run):
    (run / "report" / "certificate.pdf").unlink()


def t_certificate_replaced_event_rehashed_and_rechained(run):
    path = run / "report" / "certificate.pdf"
    path.write_bytes(path.read_bytes() + b"%% forged\n")
    events = _events(run)
    for e in events:
        if e["event"] == "certificate_written":
            e["sha256"] = _sha(path)
    _write_rechained(run, events)


def t_certificate_event_stripped_and_resigned(run):
    _resign(run, [e for e in _events(run) if e["event"] != "certificate_written"], ATTACKER)


CASES = {name[2:]: (fn, "always") for name, fn in list(globals().items())
         if name.startswith("t_") and callable(fn)}
for _name in ("retry_events_stripped_and_resigned", "operator_changed_everywhere_and_resigned",
              "limits_loosened_everywhere_and_resigned", "seals_and_key_name_stripped_and_rechained",
              "certificate_event_stripped_and_resigned"):
    CASES[_name] = (CASES[_name][0], "key")
FAULT_CASES = {"fault_events_stripped_and_rechained": "always",
               "fault_events_stripped_and_resigned": "key"}


def _tampered(source: Path, tmp_path: Path, tamper) -> Path:
    run = tmp_path / "tampered"
    shutil.copytree(source, run)
    tamper(run)
    return run


def test_the_checklist_has_at_least_the_31_cases_of_the_audit():
    assert len(CASES) + len(FAULT_CASES) >= 31


def test_untouched_run_verifies_with_and_without_the_key(signed_run, keys, capsys):
    assert main(["verify", str(signed_run), "--key", str(keys.public)]) == 0
    out = capsys.readouterr().out
    assert "authentic" in out and keys.fingerprint in out and "numbers recomputed" in out
    certificate = _events(signed_run)[-2]
    assert (f"certificate {certificate['number']}: report/certificate.pdf SHA-256 "
            f"{_sha(signed_run / 'report' / 'certificate.pdf')}") in out
    assert main(["verify", str(signed_run)]) == 0
    assert "integrity only, not authenticity" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(CASES))
def test_tampering_is_caught(name, signed_run, keys, tmp_path, capsys):
    tamper, caught = CASES[name]
    run = _tampered(signed_run, tmp_path, tamper)
    _expect(run, keys, caught, capsys)


@pytest.mark.parametrize("name", sorted(FAULT_CASES))
def test_stripping_the_fault_from_history_is_caught(name, faulted_then_resumed_run, keys,
                                                    tmp_path, capsys):
    def strip(run):
        kept = [e for e in _events(run) if e["event"] not in ("fault", "safe_state")]
        (_resign(run, kept, ATTACKER) if name.endswith("resigned")
         else _write_rechained(run, kept))

    run = _tampered(faulted_then_resumed_run, tmp_path, strip)
    _expect(run, keys, FAULT_CASES[name], capsys)


def _expect(run: Path, keys, caught: str, capsys) -> None:
    with_key = main(["verify", str(run), "--key", str(keys.public)])
    err = capsys.readouterr().err
    assert with_key == 1, "tampering not caught with the station key"
    assert "Traceback" not in err and "FAILED" in err
    without = main(["verify", str(run)])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    if caught == "always":
        assert without == 1, f"caught only with the key: {out}"
    else:
        assert without == 1 or "integrity only, not authenticity" in out


def test_malformed_line_is_named_by_number(signed_run, tmp_path):
    run = _tampered(signed_run, tmp_path, t_malformed_line)
    result = verify_run_folder(run)
    assert not result.ok and "journal.jsonl:11" in result.failure


def test_a_resigned_history_is_caught_by_the_key_and_named_by_fingerprint(signed_run, keys,
                                                                           tmp_path):
    run = _tampered(signed_run, tmp_path, t_operator_changed_everywhere_and_resigned)
    without = verify_run_folder(run)
    assert without.ok and fingerprint(ATTACKER.public_key()) in without.authenticity
    with_key = verify_run_folder(run, public_key=keys.public)
    assert not with_key.ok and "NOT AUTHENTIC" in with_key.failure


def test_an_unsigned_run_says_integrity_only(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("GYROCAL_SIGNING_KEY", raising=False)
    out = tmp_path / "run"
    assert main(["run", str(ROOT / "procedures/smoke.yaml"), "--sim", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["verify", str(out)]) == 0
    assert "integrity only, not authenticity: the run is not signed" in capsys.readouterr().out
    report = (out / "report/report.html").read_text()
    assert "Not signed" in report


def test_report_shows_the_signing_key(signed_run, keys):
    html = (signed_run / "report/report.html").read_text()
    assert keys.fingerprint in html
    assert "&lt;built-in method" not in html and "<built-in method" not in html
    results = json.loads((signed_run / "report/results.json").read_text())
    block = results.pop("signature")
    assert block["signed"] is True and block["key_fingerprint"] == keys.fingerprint
    assert block["signature"] in html and block["chain_head"] in html
    # Checked here from the documented format with the station's PEM, not with verify's code:
    # the head is the line report_written chains to, the digest is results.json unsigned.
    report_line = next(e for e in reversed(_events(signed_run)) if e["event"] == "report_written")
    assert block["chain_head"] == report_line["prev_sha256"]
    unsigned = json.dumps(results, indent=2).encode() + b"\n"
    assert block["results_sha256"] == hashlib.sha256(unsigned).hexdigest()
    station = serialization.load_pem_public_key(keys.public.read_bytes())
    payload = {"purpose": "gyrocal report",
               **{k: block[k] for k in ("run_id", "chain_head", "results_sha256",
                                        "key_fingerprint", "public_key")}}
    station.verify(base64.b64decode(block["signature"]),
                   json.dumps(payload, sort_keys=True, separators=(",", ":")).encode())


def _station_copy(keys, folder: Path):
    """The same station key in another folder, so its ledger is this test's own."""
    folder.mkdir()
    private, public = folder / "station.key", folder / "station.pub"
    shutil.copyfile(keys.private, private)
    private.chmod(0o600)
    shutil.copyfile(keys.public, public)
    return private, public, folder / "station.ledger.jsonl"


def test_a_rebuilt_report_is_sealed_again_and_verifies(signed_run, keys, tmp_path):
    private, _, _ = _station_copy(keys, tmp_path / "station")
    run = tmp_path / "rebuilt"
    shutil.copytree(signed_run, run)
    assert main(["report", str(run), "--signing-key", str(private)]) in (0, 1)
    events = _events(run)
    assert [e["event"] for e in events[-2:]] == ["report_written", "sealed"]
    assert verify_run_folder(run, public_key=keys.public).ok


def test_every_seal_is_in_the_station_ledger(signed_run, faulted_then_resumed_run, keys,
                                             capsys):
    ledger = keys.private.with_name("station.ledger.jsonl")
    assert ledger.stat().st_mode & 0o777 == 0o600
    lines = [json.loads(line) for line in ledger.read_text().splitlines()]
    # The smoke run seals twice (the run, then its certificate); the faulted run once per
    # session (run, resume).
    by_run = {}
    for line in lines:
        by_run.setdefault(line["run_dir"], []).append(line)
    assert len(by_run[str(signed_run.resolve())]) == 2
    assert len(by_run[str(faulted_then_resumed_run.resolve())]) == 2
    last = _journal(signed_run).read_bytes().splitlines(keepends=True)[-1]
    assert by_run[str(signed_run.resolve())][-1]["chain_head"] == hashlib.sha256(last).hexdigest()
    assert main(["verify", str(signed_run), "--key", str(keys.public), "--ledger",
                 str(ledger)]) == 0
    assert "ledger line" in capsys.readouterr().out
    assert main(["ledger", str(ledger)]) == 0
    assert "2 of 2 runs end where the ledger says" in capsys.readouterr().out


def test_the_ledger_notices_a_run_put_back_to_an_older_signed_state(signed_run, keys, tmp_path,
                                                                    capsys):
    """An older, genuinely signed copy passes verify even with the key; only the ledger knows."""
    private, _, ledger = _station_copy(keys, tmp_path / "station")
    older, run = tmp_path / "older", tmp_path / "run"
    shutil.copytree(signed_run, older)
    shutil.copytree(signed_run, run)
    assert main(["report", str(run), "--signing-key", str(private)]) in (0, 1)
    capsys.readouterr()
    assert verify_run_folder(run, public_key=keys.public, ledger=ledger).ok
    assert verify_run_folder(older, public_key=keys.public).ok
    put_back = verify_run_folder(older, public_key=keys.public, ledger=ledger)
    assert not put_back.ok and "replaced, cut or extended" in put_back.failure
    assert f"{ledger}:1" in put_back.failure

    shutil.rmtree(run)
    assert main(["ledger", str(ledger)]) == 1
    out = capsys.readouterr().out
    assert "CHANGED" in out and "missing" in out and "0 of 1 runs" in out


def test_a_malformed_ledger_line_is_named(signed_run, tmp_path, capsys):
    ledger = tmp_path / "station.ledger.jsonl"
    ledger.write_text('{"run_id": "x"}\n')
    assert main(["verify", str(signed_run), "--ledger", str(ledger)]) == 1
    err = capsys.readouterr().err
    assert f"{ledger}:1: not a ledger line" in err and "Traceback" not in err


def test_private_key_is_owner_only_and_refused_when_not(tmp_path, capsys):
    pair = generate_key_pair(tmp_path / "k")
    assert pair.private.stat().st_mode & 0o777 == 0o600
    pair.private.chmod(0o644)
    code = main(["run", str(ROOT / "procedures/smoke.yaml"), "--sim", "--out",
                 str(tmp_path / "run"), "--signing-key", str(pair.private)])
    assert code == 2 and "readable by others" in capsys.readouterr().err


def test_keys_are_never_overwritten(tmp_path, capsys):
    assert main(["keys", "--out", str(tmp_path)]) == 0
    first = (tmp_path / "station.key").read_bytes()
    assert main(["keys", "--out", str(tmp_path)]) == 2
    assert (tmp_path / "station.key").read_bytes() == first
    assert "never overwritten" in capsys.readouterr().err


def test_numbers_recomputed_equal_results(signed_run):
    result = verify_run_folder(signed_run)
    assert result.checked["numbers recomputed"] > 0
    sf = json.loads((signed_run / "report/results.json").read_text())["scale_factor_ls"]["sf"]
    assert np.isfinite(sf)
