"""The ACUTROL3000 driver against a scripted raw-socket peer typed from the manuals.

Every command line the peer expects is typed here from Acutronic TM-8004-C
(the ACUTROL3000 Command Language), section and page beside it; every reply
carries the prefix the manuals document: TM-8004 §2 (p. 2) says each command
is answered with an error code and a message length ahead of the data, and
TM-9374A §3.4.2 (p. 34) lays them out as two 32-bit words (error return, then
the message length in characters) followed by the null-terminated message;
TM-8004 §5.1.1 (p. 206): the controller's binary data are little-endian. The
peer packs that prefix with ``struct`` here, never with the project's codec.
Lines end with LF (TM-8004 §2.4, p. 4).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
import time

import pytest

from gyrocal.instruments.errors import (
    InstrumentProtocolError,
    InstrumentSafetyError,
)
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.instruments.table.acutrol_protocol import InterlockState, TableMode

pytestmark = pytest.mark.timeout(30)


def reply(message: str = "", code: int = 0) -> bytes:
    """Error code and length as little-endian int32, then the message and its NUL."""
    body = message.encode("ascii") + b"\x00"
    return struct.pack("<ii", code, len(body)) + body


class AclPeer:
    """Expects exact LF-terminated lines; answers each with the scripted bytes."""

    def __init__(self, script: list[tuple[str, bytes | list[bytes]]]) -> None:
        self.script = list(script)
        self.received: list[str] = []
        self.error: str | None = None
        self._server = socket.socket()
        self._server.bind(("127.0.0.1", 0))
        self._server.listen(1)
        self.port = self._server.getsockname()[1]
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    @property
    def resource(self) -> str:
        return f"TCPIP0::127.0.0.1::{self.port}::SOCKET"

    def _serve(self) -> None:
        conn, _ = self._server.accept()
        buffer = b""
        with conn:
            for expected, answer in self.script:
                while b"\n" not in buffer:
                    chunk = conn.recv(4096)
                    if not chunk:
                        self.error = f"connection closed before {expected!r}"
                        return
                    buffer += chunk
                line, buffer = buffer.split(b"\n", 1)
                self.received.append(line.decode())
                if line.decode() != expected:
                    self.error = f"expected {expected!r}, got {line.decode()!r}"
                    return
                for part in answer if isinstance(answer, list) else [answer]:
                    conn.sendall(part)
                    time.sleep(0.02)          # separate TCP segments when split
            with contextlib.suppress(OSError):
                conn.recv(1)                  # hold the line until the driver closes

    def close(self) -> None:
        self._server.close()
        self._thread.join(5)


def driver(peer: AclPeer) -> Acutrol3000Table:
    return Acutrol3000Table(peer.resource, axis=1, timeout_s=1.0, retry=RetryPolicy(attempts=1))


def run(script: list[tuple[str, bytes | list[bytes]]], action):
    peer = AclPeer(script)
    table = driver(peer)
    try:
        result = action(table)
    finally:
        table.close()
        peer.close()
    assert peer.error is None, peer.error
    assert peer.received == [line for line, _ in script]
    return result


def test_the_reply_prefix_typed_byte_by_byte():
    """*IDN? (§3.4 p. 15, the manual's example answer): 00 00 00 00 = error 0, then 50 = 0x32
    characters (49 and the NUL), little-endian."""
    idn = "Acutronic R&D USA,Acutrol3000,0,A8800-001-01.000-a"
    frame = bytes.fromhex("00000000 32000000") + idn.encode() + b"\x00"
    identity = run([("*IDN?", frame)], lambda t: t.identify())
    assert identity.description == idn


def test_queries_read_what_the_manual_answers():
    script = [
        (":Interlock? 1", reply("Fault")),            # Table 6 p. 24; §4.5.3 p. 133
        (":Mode? 1", reply("P")),                     # §4.7 p. 147 (example answer P)
        (":Read:Position? 1", reply("10.0001")),      # §4.10.4 p. 168 (example value)
        (":Read:Rate? 1", reply("-150.1234")),        # §4.10.5 p. 169
        (":Demand:Rate? 1", reply("3200.0000")),      # §4.3.6 p. 113 (example value)
        (":Limit:Acceleration? R,1", reply("1500.0")),  # §4.6.2 p. 139
    ]
    values = run(script, lambda t: (t.interlock_state(), t.read_mode(), t.read_position_deg(),
                                    t.read_rate_dps(), t.read_rate_demand_dps(),
                                    t.read_acceleration_limit_dps2()))
    assert values == (InterlockState.FAULT, TableMode.POSITION, 10.0001, -150.1234, 3200.0, 1500.0)


def test_settings_in_the_manuals_spelling_each_answered_with_error_code_zero():
    """The first change of a session takes remote lockout (§4.14.2 p. 196); the interlock is
    reset with no axis (§4.5.6 p. 136), then closed (§4.5.1 p. 131)."""
    script = [
        (":Utility:Lockout ON", reply()),
        (":Interlock:Reset", reply()),
        (":Interlock:Close 1", reply()),
        (":Mode:Rate 1", reply()),                                     # §4.7.5 p. 152
        (":Limit:Acceleration R,1,1500.000000", reply()),              # §4.6.2 p. 139
        (":Demand:Rate 1,100.000000", reply()),                        # §4.3.6 p. 113
        (":Mode:Position 1", reply()),                                 # §4.7.4 p. 151
        (":Demand:Position 1,135.223000", reply()),                    # §4.3.5 p. 112
        (":Demand:Oscillator 1,10.000000,2.500000,90.000000", reply()),  # §4.3.4 p. 111
        (":Mode:Synthesis 1", reply()),                                # §4.7.6 p. 153
        (":Demand:Rate 1,0.000000", reply()),
        (":Mode:Off 1", reply()),                                      # §4.7.3 p. 150
    ]

    def session(t: Acutrol3000Table) -> None:
        t.close_interlock()
        t.set_rate_mode()
        t.set_acceleration_limit_dps2(1500.0)
        t.set_rate_dps(100.0)
        t.set_position_mode()
        t.set_position_deg(135.223)
        t.set_oscillator(10.0, 2.5, 90.0)
        t.set_synthesis_mode()
        t.stop()
    run(script, session)


def test_queries_alone_never_take_the_lockout():
    """Reading the table changes nothing on it (station check relies on it)."""
    run([(":Interlock? 1", reply("Close")), (":Read:Rate? 1", reply("0.0"))],
        lambda t: (t.interlock_closed(), t.read_rate_dps()))


def test_a_refusal_with_the_interlock_bit_in_the_status_byte_is_a_safety_error():
    """A nonzero error code is a refusal; its text from :Query:Error? <code> (§4.9.1 p. 163);
    *STB? 65 = bits 6 and 0 (§3.10 p. 19, the manual's example): bit 0 is the system
    interlocks' summary, so the driver raises a safety error (never retried)."""
    script = [
        (":Utility:Lockout ON", reply()),
        (":Mode:Rate 1", reply(code=17)),
        (":Query:Error? 17", reply("Axis not servoed")),
        ("*STB?", reply("65")),
        ("*ESR?", reply("1")),                         # Table 1 p. 19: bit 0 MIS servo fault
    ]
    with pytest.raises(InstrumentSafetyError) as caught:
        run(script, lambda t: t.set_rate_mode())
    assert caught.value.command == ":Mode:Rate 1"
    assert caught.value.reply == "error 17 (Axis not servoed)"


def test_a_bad_message_is_a_refusal_not_worth_repeating():
    """*ESR? bit 2 (Table 1 p. 19): bad device-dependent message, e.g. axis out of range."""
    script = [
        (":Utility:Lockout ON", reply()),
        (":Demand:Rate 1,9999.000000", reply(code=4)),
        (":Query:Error? 4", reply("Parameter out of range")),
        ("*STB?", reply("128")),                       # bit 7: error queue summary only
        ("*ESR?", reply("4")),
    ]
    with pytest.raises(InstrumentProtocolError) as caught:
        run(script, lambda t: t.set_rate_dps(9999.0))
    assert caught.value.reply == "error 4 (Parameter out of range)"
    assert not caught.value.transient


def test_a_refusal_without_the_bad_message_bit_may_pass_later():
    script = [
        (":Interlock? 1", reply(code=9)),
        (":Query:Error? 9", reply("Busy")),
        ("*STB?", reply("0")),
        ("*ESR?", reply("0")),
    ]
    with pytest.raises(InstrumentProtocolError) as caught:
        run(script, lambda t: t.interlock_state())
    assert caught.value.transient and caught.value.reply == "error 9 (Busy)"


def test_the_length_frames_a_reply_split_across_segments():
    """The message length, not a terminator, ends the reply: header and message arrive in
    three TCP segments, and the message holds no line end at all."""
    frame = reply("12.5")
    run([(":Read:Rate? 1", [frame[:3], frame[3:10], frame[10:]]),
         (":Read:Position? 1", reply("270.0"))],
        lambda t: (t.read_rate_dps(), t.read_position_deg()))


def test_a_length_beyond_the_manuals_32k_is_unreadable_and_retryable():
    """§2.5 p. 5: a response is at most 32 768 characters; more means the framing is lost."""
    with pytest.raises(InstrumentProtocolError, match="unreadable reply") as caught:
        run([(":Read:Rate? 1", struct.pack("<ii", 0, 40000))], lambda t: t.read_rate_dps())
    assert caught.value.transient


@pytest.mark.parametrize(("answer", "state"), [("Close", InterlockState.CLOSE),
                                               ("OPEN", InterlockState.OPEN), ("F", InterlockState.FAULT)])
def test_interlock_answers_in_the_manuals_words(answer, state):
    assert run([(":Interlock? 1", reply(answer))], lambda t: t.interlock_state()) is state


def test_an_interlock_answer_outside_the_manual_is_unreadable():
    with pytest.raises(InstrumentProtocolError, match="Close, Open or Fault"):
        run([(":Interlock? 1", reply("1"))], lambda t: t.interlock_state())


def test_hold_demands_zero_rate_then_position_mode_and_reads_the_mode_back():
    """The safe state of a horizontal axis: zero rate demand (§4.3.6 p. 113), then position
    mode, whose servo keeps the axis positioned (§4.7.4 p. 151); the mode read back with
    :Mode? (§4.7 p. 147, letter P). No :Mode:Off (§4.7.3 p. 150) is ever sent."""
    script = [
        (":Utility:Lockout ON", reply()),
        (":Demand:Rate 1,0.000000", reply()),
        (":Mode:Position 1", reply()),
        (":Read:Rate? 1", reply("0.0004")),                   # §4.10.5 p. 169
        (":Mode? 1", reply("P")),
    ]
    result = run(script, lambda t: (t.hold(), t.read_rate_dps(), t.read_servo_mode()))
    assert result == (None, 0.0004, "position")


def test_hold_from_position_mode_goes_on_when_the_zero_rate_demand_is_refused():
    """In position mode (a tilt step) the rate demand is refused (not rate mode, *ESR? bit 2
    clear); position mode is commanded all the same."""
    script = [
        (":Utility:Lockout ON", reply()),
        (":Demand:Rate 1,0.000000", reply(code=11)),
        (":Query:Error? 11", reply("Wrong mode")),
        ("*STB?", reply("128")),
        ("*ESR?", reply("0")),
        (":Mode:Position 1", reply()),
    ]
    run(script, lambda t: t.hold())


def test_hold_with_the_interlock_open_is_a_safety_error_naming_position_mode():
    """With the interlock open both commands are refused (*STB? bit 0, §3.10 p. 19); the
    refusal of :Mode:Position is what the safe state reports."""
    refused = [("*STB?", reply("1")), ("*ESR?", reply("0"))]
    script = [
        (":Utility:Lockout ON", reply()),
        (":Demand:Rate 1,0.000000", reply(code=3)),
        (":Query:Error? 3", reply("Interlock open")),
        *refused,
        (":Mode:Position 1", reply(code=3)),
        (":Query:Error? 3", reply("Interlock open")),
        *refused,
    ]
    with pytest.raises(InstrumentSafetyError) as caught:
        run(script, lambda t: t.hold())
    assert caught.value.command == ":Mode:Position 1"
