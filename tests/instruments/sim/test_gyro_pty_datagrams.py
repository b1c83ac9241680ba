"""The simulated STIM300 serves every normal-mode datagram type (TS1524 Table 5-21) through a pty.

The station declares the type; the simulator encodes it with the datasheet's
counter (2000 / fs per datagram, §7.5.2.2.18, p. 55) and the driver, opened
on the same pty as on hardware, reads it back: every frame valid, none lost,
the type and rate recognised from the bytes, the simulated unit level and at
rest (+1 g on z for accelerometers and inclinometers).
"""

from __future__ import annotations

import numpy as np
import pytest

from gyrocal.instruments.gyro.datagram_types import NORMAL_MODE_TYPES
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.sim.gyro_pty import SimulatedGyroPort
from gyrocal.models.clock import SimClock

pytestmark = pytest.mark.timeout(60)
LSB = 2.0**-14


def source(t_s):
    return 10.0 + t_s, 25.0 + 0.0 * t_s


@pytest.mark.parametrize("identifier", sorted(NORMAL_MODE_TYPES))
@pytest.mark.parametrize("fs_hz", [125.0, 2000.0])
def test_every_declared_type_is_served_and_read_back(identifier, fs_hz):
    kind = NORMAL_MODE_TYPES[identifier]
    clock = SimClock()
    sim = SimulatedGyroPort(source, clock, sample_rate_hz=fs_hz, lsb=LSB, block_frames=32,
                            datagram=identifier, accelerometer_range_g=30)
    gyro = Stim300Gyro(sim.port_name, sample_rate_hz=fs_hz, lsb=LSB, datagram=identifier,
                       accelerometer_range_g=30, timeout_s=10)
    try:
        sim.start()
        clock.elapse_reading(100 / fs_hz)      # the controller lets 100 frames' time pass
        block = gyro.read_samples(100)
    finally:
        gyro.close()
        sim.stop()
    assert (block.crc_errors, block.lost_frames, block.garbage_bytes) == (0, 0, 0)
    assert np.all(np.diff(block.index) == 1)
    assert gyro.survey is not None and gyro.survey.layout.identifier == identifier
    assert gyro.survey.counter_step == round(2000 / fs_hz)
    assert np.all(np.diff(block.counter.astype(int)) % 256 == round(2000 / fs_hz) % 256)
    # a fresh simulated clock starts the stream at frame 0: rate = 10 + k / fs on the x axis
    assert np.allclose(block.rate, 10.0 + np.arange(100) / fs_hz, rtol=0, atol=LSB / 2)
    channels = block.channels
    assert (channels.acc_g is not None) == kind.acceleration
    assert (channels.incl_g is not None) == kind.inclination
    assert (block.temperature_c is not None) == kind.temperature
    for values in (channels.acc_g, channels.incl_g):
        if values is not None:
            assert values.tolist() == [[0.0, 0.0, 1.0]] * 100
    if kind.temperature:
        assert set(block.temperature_c.tolist()) == {25.0}
        for values in (channels.acc_temp_c, channels.incl_temp_c):
            assert values is None or set(values.ravel().tolist()) == {25.0}
    assert (channels.pps is not None) == kind.pps
