"""A Modbus connection to one controller: one pymodbus client, honest errors, bounded retries.

Both chamber drivers talk through this so that timeouts, reconnects and the
wording of errors are the same for every Modbus instrument. pymodbus' own
retries are switched off (``retries=0``): retries happen here, through
:func:`gyrocal.instruments.retry.call_with_retry`, so each one is reported.

After any transient failure the connection is closed and reopened before the
next attempt. This is deliberate: a reply that arrives after our timeout
(a slow controller, a congested serial gateway) would otherwise sit in the
socket and be read as the answer to the *next* request. RTU has no
transaction id to catch that, so the only safe cure is a fresh connection.

Not thread-safe by design: **one driver instance per thread**. A lock still
serialises calls so that misuse yields slow calls rather than crossed replies.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

import serial
from pymodbus.client.base import ModbusBaseSyncClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from gyrocal.instruments.chamber.register_map import Register
from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentError,
    InstrumentProtocolError,
    InstrumentTimeout,
    describe_reply,
)
from gyrocal.instruments.retry import RetryPolicy, call_with_retry

log = logging.getLogger(__name__)

#: Modbus exception codes and their meaning (Modbus Application Protocol v1.1b3, §7).
MODBUS_EXCEPTIONS: dict[int, str] = {
    0x01: "illegal function",
    0x02: "illegal data address",
    0x03: "illegal data value",
    0x04: "server device failure",
    0x05: "acknowledge (request accepted, still processing)",
    0x06: "server device busy",
    0x08: "memory parity error",
    0x0A: "gateway path unavailable",
    0x0B: "gateway target device failed to respond",
}

#: Codes after which the same request may succeed a moment later.
TRANSIENT_EXCEPTION_CODES = frozenset({0x05, 0x06, 0x0B})


class ModbusLink:
    """Owns one pymodbus sync client and turns every failure into an InstrumentError."""

    def __init__(
        self,
        instrument: str,
        client_factory: Callable[[Callable[[bool, bytes], bytes]], ModbusBaseSyncClient],
        unit_id: int,
        timeout_s: float,
        retry: RetryPolicy,
        on_retry: Callable[[int, InstrumentError], None] | None = None,
    ) -> None:
        self.instrument = instrument
        self.unit_id = unit_id
        self.timeout_s = timeout_s
        self.retry = retry
        self._on_retry_hook = on_retry
        self._lock = threading.Lock()
        self._last_sent = b""
        self._last_received = b""
        self._client = client_factory(self._trace_packet)
        self.retries_done = 0   # how many retries this link needed (for the journal/benchmarks)

    # ---------------------------------------------------------------- public
    def read(self, register: Register, decimals: int = 0) -> Any:
        """Read and decode one declared register (or register block)."""
        registers = self.read_raw(register.address, register.count, register.description)
        try:
            return register.decode(registers, decimals)
        except ValueError as exc:
            raise InstrumentProtocolError(
                self.instrument, f"read {register.label}", f"undecodable reply: {exc}", reply=str(registers)
            ) from exc

    def read_raw(self, address: int, count: int, description: str = "") -> list[int]:
        noun = "holding register" if count == 1 else "holding registers"
        span = f"{address}" if count == 1 else f"{address}-{address + count - 1}"
        command = f"read {noun} {span}" + (f" ({description})" if description else "")

        def once() -> list[int]:
            response = self._execute(
                command, lambda c: c.read_holding_registers(address, count=count, device_id=self.unit_id)
            )
            if len(response.registers) != count:
                raise InstrumentProtocolError(
                    self.instrument, command,
                    f"asked for {count} register(s), got {len(response.registers)}",
                    reply=self._reply_text(), transient=True,
                )
            return list(response.registers)

        return self._with_retry(once)

    def write(self, register: Register, value: float | int | str, decimals: int = 0) -> None:
        """Encode and write one declared register; checks the controller's echo."""
        command = f"write {register.label} = {value!r}"
        if not register.writable:
            raise InstrumentProtocolError(self.instrument, command, "register is read-only in the register map")
        try:
            words = register.encode(value, decimals)
        except ValueError as exc:
            raise InstrumentProtocolError(self.instrument, command, f"value not representable: {exc}") from exc

        def once() -> None:
            if len(words) == 1:
                response = self._execute(
                    command, lambda c: c.write_register(register.address, words[0], device_id=self.unit_id)
                )
                echoed = list(getattr(response, "registers", []) or [])
                if echoed and echoed != words:
                    raise InstrumentProtocolError(
                        self.instrument, command, f"controller echoed {echoed}, sent {words}",
                        reply=self._reply_text(),
                    )
            else:
                response = self._execute(
                    command, lambda c: c.write_registers(register.address, words, device_id=self.unit_id)
                )
                if getattr(response, "count", len(words)) not in (0, len(words)):
                    raise InstrumentProtocolError(
                        self.instrument, command,
                        f"controller acknowledged {response.count} register(s), sent {len(words)}",
                        reply=self._reply_text(),
                    )

        self._with_retry(once)

    def reset(self) -> None:
        """Drop the connection (and any late reply sitting in it); the next request reconnects.

        Called before the safe-state commands: an exchange cut short (a signal,
        an error between request and reply) may have left a reply in the
        socket that RTU framing cannot tell from the answer to the next request.
        """
        with self._lock:
            self._client.close()

    def close(self) -> None:
        with self._lock:
            self._client.close()

    # --------------------------------------------------------------- private
    def _with_retry(self, once: Callable[[], Any]) -> Any:
        with self._lock:
            return call_with_retry(once, self.retry, on_retry=self._on_retry, before_retry=self._reconnect)

    def _on_retry(self, attempt: int, exc: InstrumentError) -> None:
        self.retries_done += 1
        log.warning("%s: attempt %d failed (%s); reconnecting and retrying", self.instrument, attempt, exc)
        if self._on_retry_hook is not None:
            self._on_retry_hook(attempt, exc)

    def _reconnect(self) -> None:
        """Drop the connection; pymodbus reopens it on the next request."""
        self._client.close()

    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if sending:
            self._last_sent, self._last_received = data, b""
        else:
            self._last_received = data    # pymodbus passes the whole buffer so far
        return data

    def _reply_text(self) -> str | None:
        return describe_reply(self._last_received, "Modbus") if self._last_received else None

    def _execute(self, command: str, request: Callable[[ModbusBaseSyncClient], Any]) -> Any:
        try:
            response = request(self._client)
        except ModbusIOException as exc:
            self._client.close()
            raise InstrumentTimeout(
                self.instrument, command, f"no complete reply within {self.timeout_s:g} s",
                reply=self._reply_text(),
            ) from exc
        except (ConnectionException, serial.SerialException, OSError) as exc:
            self._client.close()
            raise InstrumentConnectionError(
                self.instrument, command, f"connection failed: {exc}", reply=self._reply_text()
            ) from exc
        except ModbusException as exc:
            raise InstrumentProtocolError(
                self.instrument, command, f"Modbus error: {exc}", reply=self._reply_text(), transient=True
            ) from exc
        if response.isError():
            code = int(getattr(response, "exception_code", 0))
            meaning = MODBUS_EXCEPTIONS.get(code, "unknown exception code")
            raise InstrumentProtocolError(
                self.instrument, command, f"Modbus exception {code} ({meaning})",
                reply=self._reply_text(), transient=code in TRANSIENT_EXCEPTION_CODES,
            )
        return response
