import hashlib
import json

import pytest

from gyrocal.record.journal import GENESIS_SHA256, Journal, JournalError, read_journal


def test_events_chain_by_the_hash_of_the_previous_line(tmp_path):
    path = tmp_path / "journal.jsonl"
    with Journal(path) as journal:
        journal.append("run_started", run_id="r1")
        journal.append("step_done", step_id="T01.static")
    entries = list(read_journal(path))
    assert [e.event["event"] for e in entries] == ["run_started", "step_done"]
    assert entries[0].event["prev_sha256"] == GENESIS_SHA256
    import hashlib

    assert entries[1].event["prev_sha256"] == hashlib.sha256(entries[0].raw).hexdigest()


def test_an_edited_line_is_named(tmp_path):
    path = tmp_path / "journal.jsonl"
    with Journal(path) as journal:
        for i in range(3):
            journal.append("tick", i=i)
    lines = path.read_bytes().splitlines(keepends=True)
    event = json.loads(lines[1])
    event["i"] = 99
    lines[1] = json.dumps(event, sort_keys=True, separators=(",", ":")).encode() + b"\n"
    path.write_bytes(b"".join(lines))
    with pytest.raises(JournalError, match=r"journal.jsonl:3: hash chain broken"):
        list(read_journal(path))


def test_reopening_after_a_torn_write_keeps_the_tail_aside_and_continues_the_chain(tmp_path):
    path = tmp_path / "journal.jsonl"
    with Journal(path) as journal:
        journal.append("a")
        journal.append("b")
    with open(path, "ab") as handle:
        handle.write(b'{"event":"half')
    with Journal(path) as journal:
        # the set-aside tail is named in the history at once, with the torn file's hash
        assert journal.count == 3
        journal.append("c")
    events = [e.event for e in read_journal(path)]
    assert [e["event"] for e in events] == ["a", "b", "torn_tail_set_aside", "c"]
    torn = tmp_path / "journal.torn"
    assert b'{"event":"half' in torn.read_bytes()
    assert events[2]["path"] == "journal.torn" and events[2]["bytes"] == len(b'{"event":"half')
    assert events[2]["torn_sha256"] == hashlib.sha256(torn.read_bytes()).hexdigest()
