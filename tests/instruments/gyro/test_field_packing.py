"""The compiled field packing gives the numpy encoder's datagrams byte for byte.

The numpy path of ``datagram.py`` (``_to_raw``, ``_overload_bits``, ``_put_int``) is
the oracle: every normal-mode type is encoded both ways from the same random values,
with the edges the packing must get right (halves, which round to even; values past
full scale in both directions and infinities, which clip and set overload + the axis
bit; negative values, two's complement), and the bytes compared. The field layouts
themselves are checked against the datasheet by test_gyro_datagram.py.
"""

import numpy as np
import pytest

from gyrocal.instruments.gyro import datagram, field_packing
from gyrocal.instruments.gyro.channels import SensorChannels
from gyrocal.instruments.gyro.datagram import encode_frame_array
from gyrocal.instruments.gyro.datagram_types import counter_step, counter_values

pytestmark = [
    pytest.mark.timeout(120),
    pytest.mark.skipif(not field_packing.AVAILABLE, reason="numba is missing: only numpy packs"),
]

TYPES = (0x90, 0x91, 0x92, 0x93, 0x94, 0xA5, 0xA6, 0xA7)


def _values(rng: np.random.Generator, n: int, scale: float, lsb: float) -> np.ndarray:
    """Random values with halves of an LSB, both signs of overload and infinities."""
    values = rng.normal(0.0, scale, (n, 3))
    values[::7] = (np.round(values[::7] / lsb) + 0.5) * lsb      # exact halves: round to even
    values[3::11, 0] = 1e12
    values[4::13, 1] = -1e12
    values[5::17, 2] = np.inf
    values[6::19, 0] = -np.inf
    return values


def _encode_both(monkeypatch, datagram_type: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = 600
    lsb = 2.0 ** -14
    rate = _values(rng, n, 300.0, lsb)
    temp_c = rng.normal(25.0, 60.0, (n, 3))
    temp_c[::5] = (np.round(temp_c[::5] * 256) + 0.5) / 256
    temp_c[7::23, 1] = 400.0                        # past the 16-bit temperature's full scale
    channels = SensorChannels(acc_g=_values(rng, n, 4.0, 2.0 ** -19),
                              incl_g=_values(rng, n, 1.0, 2.0 ** -22))
    counter = counter_values(np.arange(n, dtype=np.int64), counter_step(250.0))
    latency = rng.integers(0, 0x10000, n)
    status = rng.integers(0, 256, n).astype(np.uint8)

    def encode() -> np.ndarray:
        return encode_frame_array(rate, counter, status, temp_c, latency, lsb,
                                  datagram=datagram_type, channels=channels,
                                  accelerometer_range_g=10)

    monkeypatch.setattr(datagram, "_COMPILED", True)
    compiled = encode()
    monkeypatch.setattr(datagram, "_COMPILED", False)
    return compiled, encode()


@pytest.mark.parametrize("datagram_type", TYPES)
def test_compiled_packing_gives_the_numpy_bytes(monkeypatch, datagram_type):
    for seed in range(3):
        compiled, oracle = _encode_both(monkeypatch, datagram_type, seed)
        assert compiled.shape == oracle.shape
        np.testing.assert_array_equal(compiled, oracle)


def test_clipping_sets_overload_and_the_axis_bit():
    """0x90 (TS1524 Table 5-20): rates x, y, z as 24-bit fields from byte 1, their status
    at byte 10; full scale 2**23 - 1 counts; Table 5-23: overload is bit 4, x/y/z bits
    0/1/2. A rate of +1e12 on x, -inf on z, and 2.5 LSB on y (half: rounds to 2)."""
    lsb = 2.0 ** -14
    rate = np.array([[1e12, 2.5 * lsb, -np.inf]])
    frame = encode_frame_array(rate, np.zeros(1, dtype=np.int64), lsb=lsb, datagram=0x90)[0]
    assert frame[1:10].tolist() == [0x7F, 0xFF, 0xFF, 0x00, 0x00, 0x02, 0x80, 0x00, 0x01]
    assert frame[10] == 0x10 | 0x01 | 0x04


def test_nan_is_refused_with_its_row(monkeypatch):
    rate = np.zeros((5, 3))
    rate[3, 2] = np.nan
    for compiled in (True, False):
        monkeypatch.setattr(datagram, "_COMPILED", compiled)
        with pytest.raises(ValueError, match=r"rate\[3\] is NaN"):
            encode_frame_array(rate, np.arange(5))


def test_pack_ints_is_big_endian_twos_complement():
    """Expected bytes typed by hand: 0x1234 in 2 bytes, -1 in 3 bytes, 0xABCDEF in 3."""
    frames = np.zeros((1, 8), dtype=np.uint8)
    field_packing.pack_ints(frames, 0, np.array([[0x1234]]), 2)
    field_packing.pack_ints(frames, 2, np.array([[-1, 0xABCDEF]]), 3)
    assert frames[0].tolist() == [0x12, 0x34, 0xFF, 0xFF, 0xFF, 0xAB, 0xCD, 0xEF]


def _decoded_arrays(decoded) -> dict[str, np.ndarray]:
    arrays = {name: value for name, value in vars(decoded).items() if isinstance(value, np.ndarray)}
    arrays.update(decoded.channels.columns())
    return arrays


@pytest.mark.parametrize("datagram_type", TYPES)
def test_compiled_field_reads_give_the_numpy_samples(monkeypatch, datagram_type):
    """The decoder's fields read both ways from one stream: with garbage between frames
    and a corrupted frame, so the general scan (gathered, writable rows) runs besides the
    aligned one (read-only views of the received bytes)."""
    frames, _ = _encode_both(monkeypatch, datagram_type, 7)
    aligned = frames.tobytes()
    broken = frames.copy()
    broken[140, 2] ^= 0xFF
    messy = frames[:100].tobytes() + b"\x00\x13garbage" + broken[100:].tobytes()
    for stream in (aligned, messy):
        decoded = {}
        for compiled in (True, False):
            monkeypatch.setattr(datagram, "_COMPILED", compiled)
            decoder = datagram.FrameDecoder(datagram=datagram_type,
                                            counter_step=counter_step(250.0),
                                            accelerometer_range_g=10)
            decoded[compiled] = decoder.feed(stream)
        assert len(decoded[True]) > 0
        assert decoded[True].crc_errors == (stream is messy)
        assert decoded[True].crc_errors == decoded[False].crc_errors
        assert decoded[True].garbage_bytes == decoded[False].garbage_bytes
        ours, oracle = _decoded_arrays(decoded[True]), _decoded_arrays(decoded[False])
        assert ours.keys() == oracle.keys()
        for name, values in ours.items():
            assert values.dtype == oracle[name].dtype, name
            np.testing.assert_array_equal(values, oracle[name], err_msg=name)
