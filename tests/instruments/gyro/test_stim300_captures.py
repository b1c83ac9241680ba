"""Bytes from a real STIM300 (UBC Rocket captures, see captures/README.md) decode completely.

The oracle is the unit itself: its CRCs and its counter. Every datagram of
both fixtures must check (0 CRC errors, 0 garbage), the counter must show
no lost datagram at 2000 Hz (step 1) and at 125 Hz (step 16, TS1524
§7.5.2.2.18, p. 55), and the static accelerometer magnitude must be about
1 g, which holds only at the 30 g range's LSB (§7.5.2.2.7, p. 52). The
field values are checked against a reader written here with ``struct`` from
Table 5-20 (p. 36), independent of the decoder.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from ubc_captures import FAST, FRAME, SLOW, struct_reader

from gyrocal.analysis.measured_log import read_measured_log
from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main
from gyrocal.inputs import InputError
from gyrocal.instruments.gyro.capture import read_capture
from gyrocal.instruments.gyro.datagram import FrameDecoder
from gyrocal.instruments.gyro.survey import survey_stream


@pytest.mark.parametrize("path, frames, rate_hz, step", [(FAST, 400, 2000.0, 1), (SLOW, 300, 125.0, 16)])
def test_every_datagram_of_a_real_capture_checks_and_none_is_lost(path, frames, rate_hz, step):
    data = read_capture(path)
    assert len(data) == frames * FRAME
    survey = survey_stream(data)
    assert survey.layout is not None and survey.layout.identifier == 0x93 and survey.layout.crlf
    assert survey.counter_step == step and survey.sample_rate_hz == rate_hz
    decoder = FrameDecoder(datagram=0x93, crlf=True, counter_step=step, accelerometer_range_g=30)
    decoded = decoder.feed(data)
    assert (len(decoded), decoded.crc_errors, decoded.garbage_bytes, decoded.lost_frames) == (frames, 0, 0, 0)
    assert decoder.pending_bytes == 0
    assert np.array_equal(decoded.index, np.arange(frames))
    oracle = struct_reader(data, 2.0**-18)
    assert np.array_equal(decoded.rate, oracle["rate"])
    assert decoded.channels is not None
    assert np.array_equal(decoded.channels.acc_g, oracle["acc"])
    assert np.array_equal(decoded.channels.incl_g, oracle["incl"])
    assert np.array_equal(decoded.counter, oracle["counter"])
    assert np.array_equal(np.stack([decoded.status, decoded.channels.acc_status,
                                    decoded.channels.incl_status], axis=1), oracle["status"])
    assert np.array_equal(decoded.latency_us, oracle["latency"])


def test_the_old_counter_reading_would_have_lost_fifteen_of_every_sixteen():
    """Issue 23: a step of 16 read as one datagram per tick is 15 'lost' per datagram."""
    decoded = FrameDecoder(datagram=0x93, crlf=True, counter_step=1).feed(read_capture(SLOW))
    assert decoded.lost_frames == 299 * 15


@pytest.mark.parametrize("path", [FAST, SLOW])
def test_static_magnitude_says_the_accelerometer_range_is_30_g(path):
    """|a| ≈ 1 g at rest: the 30 g LSB (2^-18) gives it, the UBC reader's 5 g (2^-20) a quarter."""
    oracle = struct_reader(read_capture(path), 1.0)
    ok = (oracle["status"] == 0).all(axis=1)
    raw_magnitude = np.median(np.linalg.norm(oracle["acc"][ok], axis=1))
    incl_magnitude = np.median(np.linalg.norm(oracle["incl"][ok], axis=1))
    assert 0.98 < raw_magnitude * 2.0**-18 < 1.03
    assert 0.98 < incl_magnitude < 1.03
    assert raw_magnitude * 2.0**-20 < 0.3            # the 5 g reading: not a unit on Earth


def test_decode_command_writes_the_contract_log_and_summary(tmp_path, capsys):
    out, summary = tmp_path / "log.parquet", tmp_path / "summary.json"
    code = main(["decode", str(SLOW), "--driver", "stim300", "--accelerometer-range-g", "30",
                 "--out", str(out), "--json", str(summary)])
    printed = capsys.readouterr().out
    assert code == EXIT_OK and "0x93 (rate, acceleration, inclination)" in printed
    figures = json.loads(summary.read_text())
    assert figures["datagram_id"] == "0x93"
    assert (figures["frames_valid"], figures["crc_errors"], figures["garbage_bytes"],
            figures["lost_frames"], figures["status_flagged"]) == (300, 0, 0, 0, 0)
    assert figures["sample_rate_hz"] == 125.0
    oracle = struct_reader(read_capture(SLOW), 2.0**-18)
    assert figures["gyro_mean_dps"] == pytest.approx(oracle["rate"].mean(axis=0).tolist(), abs=1e-8)
    assert figures["accelerometer_mean_g"] == pytest.approx(oracle["acc"].mean(axis=0).tolist(), abs=1e-8)
    assert figures["inclinometer_mean_g"] == pytest.approx(oracle["incl"].mean(axis=0).tolist(), abs=1e-8)
    log = read_measured_log(out)                 # the contract's reader accepts it
    assert len(log) == 300 and log.sample_rate_hz == pytest.approx(125.0)
    import pyarrow.parquet as pq

    table = pq.read_table(out)
    for name in ("acc_x_g", "acc_y_g", "acc_z_g", "incl_x_g", "incl_y_g", "incl_z_g",
                 "acc_status", "incl_status", "gyro_status", "gyro_x"):
        assert name in table.column_names
    assert np.array_equal(table["acc_z_g"].to_numpy(), oracle["acc"][:, 2])


def test_decode_at_the_wrong_range_says_so(capsys):
    assert main(["decode", str(FAST), "--driver", "stim300"]) == EXIT_OK
    assert "probably another one" in capsys.readouterr().out


def test_the_startup_datagrams_are_counted_as_status_flagged(tmp_path, capsys):
    summary = tmp_path / "s.json"
    assert main(["decode", str(FAST), "--driver", "stim300", "--json", str(summary)]) == EXIT_OK
    figures = json.loads(summary.read_text())
    oracle = struct_reader(read_capture(FAST), 1.0)
    assert figures["status_flagged"] == int((oracle["status"] != 0).any(axis=1).sum()) > 0
    assert (figures["frames_valid"], figures["lost_frames"], figures["sample_rate_hz"]) == (400, 0, 2000.0)


@pytest.mark.parametrize("content, expected", [
    (b"147 256 1", "bad.txt:1: value 256 (number 2) is not a byte"),
    (b"147 12 255 0 0\n7 0 x 9 10\n", "bad.txt:2: not a byte capture"),
    (bytes(range(200)) * 3, "no STIM300 normal-mode datagram"),
    (b"", "empty capture"),
])
def test_bad_captures_are_bad_input_naming_the_file(tmp_path, capsys, content, expected):
    path = tmp_path / "bad.txt"
    path.write_bytes(content)
    code = main(["decode", str(path), "--driver", "stim300"])
    text = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and expected in text and "Traceback" not in text


def test_a_missing_capture_is_named():
    with pytest.raises(InputError, match="nope.bin: file not found"):
        read_capture("nope.bin")


def test_decode_writes_a_csv_log_the_contract_reader_accepts(tmp_path, capsys):
    out = tmp_path / "log.csv"
    assert main(["decode", str(FAST), "--driver", "stim300", "--accelerometer-range-g", "30",
                 "--chamber-temp-c", "21.5", "--out", str(out)]) == EXIT_OK
    log = read_measured_log(out)
    assert len(log) == 400 and log.sample_rate_hz == pytest.approx(2000.0)
    assert set(log.chamber_temp_c.tolist()) == {21.5}
    assert np.array_equal(log.gyro, struct_reader(read_capture(FAST), 1.0)["rate"][:, 0])


def test_an_unwritable_output_is_bad_input_naming_it(tmp_path, capsys):
    out = tmp_path / "missing-folder" / "log.parquet"
    assert main(["decode", str(SLOW), "--driver", "stim300", "--out", str(out)]) == EXIT_BAD_INPUT
    assert f"--out {out}: cannot write" in capsys.readouterr().err
