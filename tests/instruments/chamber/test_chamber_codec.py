"""Register values of the controllers' encodings, from their manuals, through the product's path.

The conversions are pymodbus's (``modbus_codec`` adds the implied decimals, the
F4T's text and the range checks); every expected register below is worked by
hand from the manual's data layout, never produced by an encoder.

Sources (docs/protocol-elements.md, "Chamber"):
- F4P: Watlow Series F4P user's manual (page numbers from its page footers) —
  p. 6.4, Operations Page table, "Proportional Band": the Modbus value is an integer
  in units, tenths, hundredths or thousandths; p. 6.13, Setup Page table, "Decimal"
  (register 606): 0 to 3 decimals; p. 9.2, alphabetical register list, 302 "Alarm 1
  Low Deviation": -19999 to -1, so registers are signed; p. 9.11, "Parameters Sorted
  by Modbus Register": 100 "Input 1 Value", 300 "Set Point 1". ESPEC-4
  (ChamberConnectLibrary ``modbus.py``, ``read_holding_signed``) reads them as signed
  16-bit.
- F4T: Watlow F4T Setup and Operations User's Guide 0600-0093-0000 Rev. F, p. 231
  (loop block: set point 2782, process value 2820 are floats) and p. 225 (part number
  16-30 one character per register, serial 12 and software release 4 as integers);
  ESPEC-T (``modbus.py``: two registers per float or integer, low word first by default).
"""

import pytest
from modbus_rtu import rtu_frame, rtu_frame_ok
from pymodbus.framer.rtu import FramerRTU

from gyrocal.instruments.chamber import modbus_codec as codec
from gyrocal.instruments.chamber.register_map import Encoding, Register, register_table

pytestmark = pytest.mark.timeout(10)

F4_SETPOINT = Register("setpoint", 300, Encoding.INT16_DECIMALS, True, "set point 1")
F4T_SETPOINT = Register("setpoint", 2782, Encoding.FLOAT32_LWF, True, "set point")
F4T_SERIAL = Register("serial_number", 12, Encoding.INT32_LWF, False, "serial number")
F4T_PART = Register("part_number", 16, Encoding.TEXT, False, "part number", text_count=15)


# F4P p. 6.4 / p. 6.13: value × 10^decimals as a signed 16-bit register (two's complement
# worked by hand: a negative n is 0x10000 + n).
INT16_PAIRS = [
    (23.1, 1, 0x00E7),        # 231
    (-40.0, 1, 0xFE70),       # -400 = 0x10000 - 400
    (-0.1, 1, 0xFFFF),        # -1
    (0.0, 1, 0x0000),
    (3276.7, 1, 0x7FFF),      # int16 max
    (-3276.8, 1, 0x8000),     # int16 min
    (150.0, 0, 0x0096),
    (-12.34, 2, 0xFB2E),      # -1234
    (-1.999, 3, 0xF831),      # -1999 (3 decimals, the F4P's largest setting)
]


@pytest.mark.parametrize(("value", "decimals", "register"), INT16_PAIRS)
def test_f4_int16_with_implied_decimals_matches_hand_worked_registers(value, decimals, register):
    assert F4_SETPOINT.encode(value, decimals) == [register]
    assert F4_SETPOINT.decode([register], decimals) == pytest.approx(value, abs=1e-9)


@pytest.mark.parametrize(("value", "decimals"), [(3276.8, 1), (-3276.9, 1), (float("nan"), 1), (400.0, 2)])
def test_int16_refuses_values_that_do_not_fit(value, decimals):
    with pytest.raises(ValueError):
        F4_SETPOINT.encode(value, decimals)


# F4T p. 231 with ESPEC-T: IEEE-754 float32, the low 16 bits in the first register.
# The bit patterns are worked by hand: sign, 8-bit exponent (bias 127), 23-bit fraction.
FLOAT_PAIRS = [
    (25.0, [0x0000, 0x41C8]),      # 0x41C80000: 1.5625 × 2^4
    (-40.0, [0x0000, 0xC220]),     # 0xC2200000: -1.25 × 2^5
    (23.1, [0xCCCD, 0x41B8]),      # 0x41B8CCCD (23.1 rounded to float32)
    (1.0, [0x0000, 0x3F80]),
]


@pytest.mark.parametrize(("value", "registers"), FLOAT_PAIRS)
def test_f4t_float32_is_sent_low_word_first(value, registers):
    assert F4T_SETPOINT.encode(value) == registers
    assert F4T_SETPOINT.decode(registers) == pytest.approx(value, rel=1e-7)


@pytest.mark.parametrize(("value", "registers"), FLOAT_PAIRS)
def test_high_word_first_is_the_same_words_swapped(value, registers):
    high_first = Register("setpoint", 2782, Encoding.FLOAT32_HWF, True, "set point")
    assert high_first.encode(value) == registers[::-1]
    assert high_first.decode(registers[::-1]) == pytest.approx(value, rel=1e-7)


@pytest.mark.parametrize(("value", "registers"), [(1234567, [0xD687, 0x0012]), (-2, [0xFFFE, 0xFFFF]), (7, [7, 0])])
def test_f4t_int32_is_sent_low_word_first(value, registers):
    assert F4T_SERIAL.encode(value) == registers          # 1234567 = 0x0012D687
    assert F4T_SERIAL.decode(registers) == value


def test_f4t_text_holds_one_character_per_register():
    # F4T p. 225: one ASCII character in each register's low byte ("F" 0x46, "4" 0x34, "T" 0x54)
    assert F4T_PART.encode("F4T") == [0x46, 0x34, 0x54] + [0] * 12
    assert F4T_PART.decode([0x46, 0x34, 0x54] + [0] * 12) == "F4T"


def test_decoders_refuse_a_wrong_count_or_an_impossible_register():
    with pytest.raises(ValueError, match="expected 2 register"):
        F4T_SETPOINT.decode([0x41C8])
    with pytest.raises(ValueError, match="outside 0..65535"):
        F4T_SETPOINT.decode([0x10000, 0])
    with pytest.raises(ValueError, match="outside 0..65535"):
        codec.decode_int16_decimals(-1, 1)


def test_values_that_no_register_holds_are_value_errors_naming_the_register():
    with pytest.raises(ValueError, match=r"holding registers 2782-2783 \(set point\).*float32"):
        F4T_SETPOINT.encode(1e39)
    with pytest.raises(ValueError, match=r"holding register 606 \(decimals\).*uint16"):
        Register("decimals", 606, Encoding.UINT16, False, "decimals").encode(70000)
    with pytest.raises(ValueError, match="int32"):
        F4T_SERIAL.encode(2**31)


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
