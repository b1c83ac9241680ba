"""Byte pairs for the pure encodings, taken from manuals or worked by hand (not from the code)."""

import pytest
from modbus_rtu import rtu_frame, rtu_frame_ok
from pymodbus.framer.rtu import FramerRTU

from gyrocal.instruments.chamber import modbus_codec as codec
from gyrocal.instruments.chamber.register_map import Encoding, Register, register_table

pytestmark = pytest.mark.timeout(10)


# value, decimals, register: hand-worked two's complement
INT16_PAIRS = [
    (23.1, 1, 0x00E7),        # 231
    (-40.0, 1, 0xFE70),       # -400 = 0x10000 - 400
    (-0.1, 1, 0xFFFF),        # -1
    (0.0, 1, 0x0000),
    (3276.7, 1, 0x7FFF),      # int16 max
    (-3276.8, 1, 0x8000),     # int16 min
    (150.0, 0, 0x0096),
    (-12.34, 2, 0xFB2E),      # -1234
]


@pytest.mark.parametrize(("value", "decimals", "register"), INT16_PAIRS)
def test_int16_with_implied_decimals_matches_hand_worked_registers(value, decimals, register):
    assert codec.encode_int16_decimals(value, decimals) == register
    assert codec.decode_int16_decimals(register, decimals) == pytest.approx(value, abs=1e-9)


@pytest.mark.parametrize(("value", "decimals"), [(3276.8, 1), (-3276.9, 1), (float("nan"), 1), (400.0, 2)])
def test_int16_refuses_values_that_do_not_fit(value, decimals):
    with pytest.raises(ValueError):
        codec.encode_int16_decimals(value, decimals)


# value, [low word, high word]: IEEE-754 bit patterns worked by hand
FLOAT_PAIRS = [
    (25.0, [0x0000, 0x41C8]),      # 0x41C80000
    (-40.0, [0x0000, 0xC220]),     # 0xC2200000
    (23.1, [0xCCCD, 0x41B8]),      # 0x41B8CCCD (23.1 rounded to float32)
    (1.0, [0x0000, 0x3F80]),
]


@pytest.mark.parametrize(("value", "registers"), FLOAT_PAIRS)
def test_float32_is_sent_low_word_first(value, registers):
    assert codec.encode_float32_low_word_first(value) == registers
    assert codec.decode_float32_low_word_first(registers) == pytest.approx(value, rel=1e-7)


@pytest.mark.parametrize(("value", "registers"), [(1234567, [0xD687, 0x0012]), (-2, [0xFFFE, 0xFFFF]), (7, [7, 0])])
def test_int32_is_sent_low_word_first(value, registers):
    assert codec.encode_int32_low_word_first(value) == registers
    assert codec.decode_int32_low_word_first(registers) == value


def test_text_holds_one_character_per_register():
    assert codec.encode_text_one_char_per_register("F4T", 5) == [0x46, 0x34, 0x54, 0, 0]
    assert codec.decode_text_one_char_per_register([0x46, 0x34, 0x54, 0, 0]) == "F4T"


def test_two_register_decoders_refuse_a_wrong_count():
    with pytest.raises(ValueError, match="expected 2 registers"):
        codec.decode_float32_low_word_first([0x41C8])


# Complete RTU frames. The first is the brief's "read holding register 100 from
# unit 1"; the others are the worked examples of Watlow's Modbus communications
# guide (exception replies included). That guide, as reproduced online, also
# prints "01 06 00 2D 00 01 D8 C3"; both CRCs here give D8 03, so it is left
# out as a probable transcription error.
MANUAL_RTU_FRAMES = [
    "01 03 00 64 00 01 C5 D5",
    "01 02 00 01 00 02 A8 0B",
    "01 82 01 81 60",
    "01 86 02 C3 A1",
    "01 06 00 07 2E E0 24 23",
    "01 86 03 02 61",
]


@pytest.mark.parametrize("frame_hex", MANUAL_RTU_FRAMES)
def test_crc16_reproduces_the_manual_frames(frame_hex):
    frame = bytes.fromhex(frame_hex)
    assert rtu_frame(frame[0], frame[1:-2]) == frame
    assert rtu_frame_ok(frame)
    # pymodbus' own CRC as a second, independent oracle
    assert FramerRTU.compute_CRC(frame[:-2]).to_bytes(2, "big") == frame[-2:]


def test_a_corrupted_frame_fails_the_crc():
    frame = bytearray.fromhex("01 03 00 64 00 01 C5 D5")
    frame[3] ^= 0x01
    assert not rtu_frame_ok(bytes(frame))


def test_register_table_refuses_overlaps_and_duplicates():
    pv = Register("pv", 2820, Encoding.FLOAT32_LWF, False, "pv")
    with pytest.raises(ValueError, match="overlaps"):
        register_table(pv, Register("other", 2821, Encoding.UINT16, False, "x"))
    with pytest.raises(ValueError, match="twice"):
        register_table(pv, Register("pv", 1, Encoding.UINT16, False, "x"))


def test_register_labels_name_the_addresses():
    assert Register("sp", 300, Encoding.INT16_DECIMALS, True, "set point 1").label == (
        "holding register 300 (set point 1)"
    )
    assert Register("pv", 2820, Encoding.FLOAT32_LWF, False, "pv").label == "holding registers 2820-2821 (pv)"
