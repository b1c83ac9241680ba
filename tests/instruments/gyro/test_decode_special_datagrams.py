"""``gyrocal decode`` on a capture holding special datagrams: cut out, decoded, reported.

A unit sends part number, serial number and configuration at start-up before
normal mode (TS1524 §7.5.1, p. 47), and a configuration datagram in place of
the next normal-mode datagram(s) when asked ``C`` (§8.1–8.4, pp. 58–59). The
special datagrams are typed from Tables 5-13/5-14 (p. 29), 5-15 (p. 30) and
5-16 (pp. 31–33), with CR LF (identifiers 0xB3, 0xB7, 0xBD) as the real UBC
capture they are joined to (0x93 with CR LF, 125 Hz; captures/README.md).
"""

from __future__ import annotations

import json

import pytest
from crc_reference import bitwise_crc32_mpeg2
from stim300_bytes import PART_BODY, SERIAL_BODY, hand_configuration
from ubc_captures import FRAME, SLOW

from gyrocal.analysis.measured_log import read_measured_log
from gyrocal.cli import EXIT_OK, main
from gyrocal.instruments.gyro.capture import read_capture


def _with_crlf(identifier: int, body: bytes) -> bytes:
    """Tables 5-13/5-15: the CR LF identifier, the body, CRC-32 (no dummy bytes, Table 5-22), CR LF."""
    body = bytes([identifier]) + body[1:]
    return body + bitwise_crc32_mpeg2(body).to_bytes(4, "big") + b"\r\n"


def test_start_up_datagrams_and_an_answer_are_reported_not_garbage_or_lost(tmp_path, capsys):
    frames = read_capture(SLOW)                                   # 300 real 0x93 datagrams
    start_up = _with_crlf(0xB3, PART_BODY) + _with_crlf(0xB7, SERIAL_BODY) + hand_configuration(True)
    answer = hand_configuration(True)                             # answer to C, replacing datagrams 100-101
    capture = start_up + frames[:100 * FRAME] + answer + frames[102 * FRAME:]
    path, summary, log = tmp_path / "start-up.bin", tmp_path / "s.json", tmp_path / "log.parquet"
    path.write_bytes(capture)
    code = main(["decode", str(path), "--driver", "stim300", "--accelerometer-range-g", "30",
                 "--json", str(summary), "--out", str(log)])
    printed = capsys.readouterr().out
    assert code == EXIT_OK
    figures = json.loads(summary.read_text())
    assert (figures["frames_valid"], figures["crc_errors"], figures["garbage_bytes"],
            figures["incomplete_tail_bytes"], figures["lost_frames"], figures["replaced_frames"]) \
        == (298, 0, 0, 0, 0, 2)
    assert (figures["part_number"], figures["part_number_revision"], figures["serial_number"]) \
        == ("84167-4400003-321", "K", "N25582405002002")
    assert figures["duration_s"] == 300 / 125.0
    placed = [(s["kind"], s["datagram_id"], s["byte_offset"], s["bytes"], s["after_frames"],
               s["replaced_frames"]) for s in figures["special_datagrams"]]
    assert placed == [("part number", "0xB3", 0, 22, 0, None),
                      ("serial number", "0xB7", 22, 22, 0, None),
                      ("configuration", "0xBD", 44, 28, 0, None),
                      ("configuration", "0xBD", 72 + 100 * FRAME, 28, 100, 2)]
    assert figures["special_datagrams"][1]["value"] == {"serial_number": "N25582405002002"}
    assert figures["special_datagrams"][3]["value"] == figures["unit_configuration"]
    assert figures["unit_configuration"]["accelerometer_range_g"] == [30, 30, 30]
    assert "at 250.0 Hz; the stream is 0x93 at 125 Hz" in figures["configuration_note"]
    assert "part number 84167-4400003-321 rev K" in printed and "serial N25582405002002" in printed
    measured = read_measured_log(log)                              # time runs on across the answer
    assert len(measured) == 298
    assert measured.t_s[100] - measured.t_s[99] == pytest.approx(3 / 125.0)


def test_a_capture_without_special_datagrams_reports_none(tmp_path):
    summary = tmp_path / "s.json"
    assert main(["decode", str(SLOW), "--driver", "stim300", "--json", str(summary)]) == EXIT_OK
    figures = json.loads(summary.read_text())
    assert figures["special_datagrams"] == [] and figures["replaced_frames"] == 0
    assert "serial_number" not in figures and "unit_configuration" not in figures
