"""A real unit's bytes replayed on a pty, read by the real driver (issue 23, replay).

The oracle is the capture itself (UBC Rocket, tests/instruments/gyro/captures):
what the driver returns must be its datagrams, in order, read field by field
by ``struct_reader``; a station that declares another datagram or rate than
the bytes carry is a fault naming both.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from ubc_captures import SLOW, struct_reader

from gyrocal.cli import EXIT_FAULT, main
from gyrocal.instruments.errors import InstrumentProtocolError
from gyrocal.instruments.gyro.capture import read_capture
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.sim.replay_pty import ReplayGyroPort
from gyrocal.models.clock import RealClock
from gyrocal.orchestrator.station import load_station
from tests.support.sim_serve import served_station

pytestmark = pytest.mark.timeout(240)
REPO = Path(__file__).resolve().parents[3]
SPEED = 4.0


def test_the_driver_reads_the_replayed_capture_byte_for_byte_at_its_rate():
    data = read_capture(SLOW)
    oracle = struct_reader(data, 2.0**-18)
    replay = ReplayGyroPort(data, RealClock(SPEED), loop=False)
    assert (replay.sample_rate_hz, replay.survey.layout.identifier) == (125.0, 0x93)
    # opened before the first byte is sent (pyserial flushes the input when it opens a port)
    gyro = Stim300Gyro(replay.port_name, sample_rate_hz=125, datagram=0x93, crlf=True,
                       accelerometer_range_g=30, axis="y", timeout_s=10)
    with replay:
        try:
            started = time.monotonic()
            block = gyro.read_samples(250)
            wall_s = time.monotonic() - started
        finally:
            gyro.close()
    assert (block.crc_errors, block.garbage_bytes, block.lost_frames) == (0, 0, 0)
    assert np.array_equal(block.rate_xyz, oracle["rate"][:250])
    assert np.array_equal(block.rate, oracle["rate"][:250, 1])
    assert np.array_equal(block.channels.acc_g, oracle["acc"][:250])
    assert np.array_equal(block.channels.incl_g, oracle["incl"][:250])
    assert np.array_equal(block.index, np.arange(250))
    # paced at the capture's rate: 250 datagrams at 125 Hz are 2 s, 0.5 s at 4× (not dumped at once)
    assert wall_s > 0.5 * (250 / 125.0) / SPEED


@pytest.mark.parametrize("declared, expected", [
    (dict(datagram=0x94, crlf=False, sample_rate_hz=125),
     "the unit sends 0x93 (rate, acceleration, inclination) with CR LF; the station declares "
     "0x94 (rate, temperature)"),
    (dict(datagram=0x93, crlf=True, sample_rate_hz=250),
     "the unit's counter steps 16 per datagram, i.e. 125 Hz"),
])
def test_a_wrong_declaration_is_a_fault_naming_both(declared, expected):
    replay = ReplayGyroPort(read_capture(SLOW), RealClock(SPEED), loop=False)
    gyro = Stim300Gyro(replay.port_name, timeout_s=5, **declared)
    with replay:
        try:
            with pytest.raises(InstrumentProtocolError) as caught:
                gyro.read_samples(50)
        finally:
            gyro.close()
    assert expected in str(caught.value)
    assert not caught.value.transient


def test_sim_serve_replays_a_capture_for_a_driver_built_from_the_written_station(tmp_path):
    written = tmp_path / "live-station.yaml"
    proc = subprocess.Popen(
        [sys.executable, "-m", "gyrocal", "sim", "serve", "--station", "stations/sim.yaml",
         "--replay-gyro", str(SLOW), "--write-station", str(written)],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            lines.append(line)
            if "station file with these addresses" in line:
                break
        assert written.exists(), "".join(lines) + proc.stderr.read()
        assert any("replaying" in line and "0x93" in line for line in lines)
        g = load_station(written).gyro
        assert (g.datagram, g.crlf, g.sample_rate_hz) == (0x93, True, 125.0)
        gyro = Stim300Gyro(g.port, sample_rate_hz=g.sample_rate_hz, datagram=g.datagram, crlf=g.crlf,
                           accelerometer_range_g=30)
        try:
            block = gyro.read_samples(100, timeout_s=5.0)
        finally:
            gyro.close()
        oracle = struct_reader(read_capture(SLOW), 2.0**-18)
        first = int(np.flatnonzero((oracle["counter"] == block.counter[0])
                                   & (oracle["rate"][:, 0] == block.rate_xyz[0, 0]))[0])
        assert np.array_equal(block.rate_xyz, oracle["rate"][first:first + 100])
        assert block.crc_errors == 0 and block.lost_frames == 0
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
        assert "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def test_a_run_whose_station_misdeclares_the_replayed_unit_faults_naming_both(tmp_path, capsys):
    """The real path: `gyrocal run --station` against sim serve replaying the 0x93 capture,
    with the station edited to declare 0x94: a fault at connect (exit 3) that names both."""
    live = tmp_path / "live.yaml"
    with served_station(live, extra_args=("--replay-gyro", str(SLOW))):
        text = live.read_text(encoding="utf-8").replace("datagram: '0x93'", "datagram: '0x94'")
        assert "datagram: '0x94'" in text
        wrong = tmp_path / "wrong.yaml"
        wrong.write_text(text.replace("crlf: true", "crlf: false"), encoding="utf-8")
        smoke = (REPO / "procedures" / "smoke.yaml").read_text(encoding="utf-8")
        procedure = tmp_path / "smoke.yaml"
        procedure.write_text(smoke.replace("sample_rate_hz: 2000", "sample_rate_hz: 125"),
                             encoding="utf-8")
        code = main(["run", str(procedure), "--station", str(wrong), "--out", str(tmp_path / "run"),
                     "--allow-outside-paths"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT, err
    assert "the unit sends 0x93 (rate, acceleration, inclination) with CR LF; the station declares " \
           "0x94 (rate, temperature)" in err
    assert "Traceback" not in err
