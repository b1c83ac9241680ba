"""Simulated Watlow chambers: real Modbus servers on loopback backed by ChamberPhysics.

The drivers reach these through exactly the transports they use on hardware
(RTU frames over a TCP serial gateway for the F4, Modbus TCP for the F4T), so
a dry run exercises the real driver code.

pymodbus 3.16 ignores subclassed datablocks, so the registers are declared as
a :class:`~pymodbus.simulator.SimDevice` built from the driver's register map,
and an async ``action`` callback fills them from the physics at
``clock.now_s()`` on every read and applies setpoint writes.

Faults (armed on :attr:`faults`, a :class:`FaultInjector` over :data:`FAULTS`):

- ``modbus_exception`` (param ``code``, default 4): the request is answered
  with that Modbus exception code; returned from the ``action`` callback.
- ``late_reply`` (param ``delay_s``, default 0.5): the ``action`` sleeps
  before the registers are served, so the whole reply is late.
- ``no_reply``: the request is processed but the reply is not sent.
- ``drop_connection``: no reply, and every open connection is closed.
  pymodbus' server cannot express these two in the datastore API (a reply is
  always built), so they are done at the transport level: the server's
  ``trace_packet`` hook sees every outgoing frame and returns ``b""``, which
  sends nothing; for a drop, the open connections are then closed.
- ``never_reaches_setpoint`` (param ``capacity``): persistent; sets
  ``physics.stuck`` so the PV stalls short of the setpoint.
- ``alarm`` (param ``state`` for the F4T, default 7 "alarm high"): persistent;
  the status register (F4T) or the limit controller's digital input (F4:
  status 201 equal to its condition 1061, F4P manual pp. 9.4-9.5) reports an
  alarm regardless of the physics.
- ``profile_running``: persistent; the controller runs its own profile (F4:
  register 200 reads 2; F4T: register 16568 reads 149, Espec's "running").

Per-request faults (the first four) consume one firing per request; the two
persistent ones are read, not consumed, and take effect at the next request
served (or at once via :meth:`apply_persistent_faults`).
"""

from __future__ import annotations

import asyncio
import logging
import threading
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from gyrocal.instruments.chamber.register_map import Register
from gyrocal.instruments.chamber.watlow_f4 import (
    F4_MODEL_NUMBER,
    F4_REGISTERS,
    digital_input_registers,
)
from gyrocal.instruments.chamber.watlow_f4t import (
    ALARM_STATE_HIGH,
    ALARM_STATE_LOW,
    ALARM_STATE_NONE,
    DEVICE_STATUS_OK,
    DISPLAY_UNITS_C,
    DISPLAY_UNITS_F,
    F4T_REGISTERS,
    PROFILE_STATE_RUNNING,
)
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.models.chamber import ChamberPhysics

log = logging.getLogger(__name__)

FAULTS: tuple[str, ...] = (
    "no_reply",
    "late_reply",
    "modbus_exception",
    "drop_connection",
    "never_reaches_setpoint",
    "alarm",
    "profile_running",
)

_WRITE_FUNCTION_CODES = frozenset({6, 16, 22, 23})
_START_TIMEOUT_S = 5.0


class _SimulatedModbusChamber:
    """A Modbus server thread serving one controller's register map from ChamberPhysics."""

    MODEL = "chamber"
    FRAMER = FramerType.SOCKET
    REGISTERS: dict[str, Register] = {}

    def __init__(
        self,
        physics: ChamberPhysics,
        faults: FaultInjector | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        unit_id: int = 1,
    ) -> None:
        self.physics = physics
        self.faults = faults or FaultInjector(FAULTS, owner=f"simulated {self.MODEL}")
        missing = [name for name in FAULTS if name not in self.faults.known]
        if missing:
            raise ValueError(f"simulated {self.MODEL}: fault injector does not know {missing}")
        self.host = host
        self.port = port
        self.unit_id = unit_id
        self.requests_served = 0
        self._state_lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._ready = threading.Event()
        self._startup_error: BaseException | None = None
        self._bound_port: int | None = None
        self._stuck_by_fault = False

    # --------------------------------------------------------------- lifecycle
    @property
    def bound_port(self) -> int:
        if self._bound_port is None:
            raise RuntimeError(f"simulated {self.MODEL} is not running")
        return self._bound_port

    @property
    def address(self) -> str:
        raise NotImplementedError

    def start(self) -> _SimulatedModbusChamber:
        with self._state_lock:
            if self._thread is not None:
                return self
            self._ready.clear()
            self._startup_error = None
            self._thread = threading.Thread(target=self._run, name=f"sim-{self.MODEL}", daemon=True)
            self._thread.start()
        if not self._ready.wait(_START_TIMEOUT_S):
            raise RuntimeError(f"simulated {self.MODEL} did not start within {_START_TIMEOUT_S} s")
        if self._startup_error is not None:
            self._thread.join(_START_TIMEOUT_S)
            self._thread = None
            raise RuntimeError(
                f"simulated {self.MODEL} could not listen on {self.host}:{self.port}: {self._startup_error}"
            ) from self._startup_error
        return self

    def stop(self) -> None:
        with self._state_lock:
            thread, loop, server = self._thread, self._loop, self._server
            self._thread = None
        if thread is None:
            return
        if loop is not None and server is not None and loop.is_running():
            future = asyncio.run_coroutine_threadsafe(server.shutdown(), loop)
            future.result(timeout=_START_TIMEOUT_S)
        thread.join(_START_TIMEOUT_S)
        self._bound_port = None
        self._loop = self._server = None

    def __enter__(self) -> _SimulatedModbusChamber:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def apply_persistent_faults(self) -> None:
        """Make ``never_reaches_setpoint`` take effect now rather than at the next request."""
        params = self.faults.params("never_reaches_setpoint")
        armed = params is not None
        if armed == self._stuck_by_fault:
            return   # leave a stuck flag set directly on the physics alone
        if armed and "capacity" in params:
            self.physics.stuck_capacity = float(params["capacity"])
        self.physics.stuck = armed
        self._stuck_by_fault = armed

    # ---------------------------------------------------------- model hooks
    def _value(self, register: Register) -> float | int | str:
        raise NotImplementedError

    def _decimals(self) -> int:
        return 0

    # ------------------------------------------------------------- internals
    def _run(self) -> None:
        asyncio.run(self._serve())

    async def _serve(self) -> None:
        try:
            simdata = [
                SimData(address=reg.address, count=reg.count, values=0,
                        datatype=DataType.REGISTERS, readonly=not reg.writable)
                for reg in self.REGISTERS.values()
            ]
            device = SimDevice(id=self.unit_id, simdata=simdata, action=self._action)
            server = ModbusTcpServer(
                device, framer=self.FRAMER, address=(self.host, self.port), trace_packet=self._trace_packet
            )
            await server.serve_forever(background=True)
            self._server = server
            self._loop = asyncio.get_running_loop()
            self._bound_port = server.transport.sockets[0].getsockname()[1]
        except Exception as exc:   # reported to start() in the caller's thread
            self._startup_error = exc
            self._ready.set()
            return
        self._ready.set()
        await server.serving

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        # pymodbus calls the action twice for a write: with the values, then
        # (values None) to build the echo. Faults apply to the request once.
        is_write_echo = set_values is None and function_code in _WRITE_FUNCTION_CODES
        if not is_write_echo:
            self.requests_served += 1
            params = self.faults.take("modbus_exception")
            if params is not None:
                return _exception_code(params.get("code", ExcCodes.DEVICE_FAILURE))
            params = self.faults.take("late_reply")
            if params is not None:
                await asyncio.sleep(float(params.get("delay_s", 0.5)))
            self.apply_persistent_faults()
        if set_values is not None:
            return self._write(address, [int(v) for v in set_values])
        self._fill(start_address, address, count, registers)
        return None

    def _fill(self, start_address: int, address: int, count: int, registers: list[int]) -> None:
        end = address + count
        for reg in self.REGISTERS.values():
            if reg.address < end and address < reg.address + reg.count:
                words = reg.encode(self._value(reg), self._decimals())
                offset = reg.address - start_address
                registers[offset: offset + reg.count] = words

    def _write(self, address: int, words: list[int]) -> ExcCodes | None:
        for reg in self.REGISTERS.values():
            if reg.address == address and reg.count == len(words) and reg.writable:
                value = reg.decode(words, self._decimals())
                try:
                    self._apply_write(reg, value)
                except ValueError as exc:
                    log.info("simulated %s refused %s = %r: %s", self.MODEL, reg.name, value, exc)
                    return ExcCodes.ILLEGAL_VALUE
                return None
        return ExcCodes.ILLEGAL_ADDRESS

    def _apply_write(self, register: Register, value: Any) -> None:
        if register.name != "setpoint":
            raise ValueError(f"{register.name} is not writable in the simulator")
        self.physics.set_setpoint(float(value))

    def _alarm_forced(self) -> bool:
        return self.faults.params("alarm") is not None

    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if not sending:
            return data
        if self.faults.take("drop_connection") is not None:
            assert self._loop is not None
            self._loop.call_soon(self._drop_connections)
            return b""
        if self.faults.take("no_reply") is not None:
            return b""
        return data

    def _drop_connections(self) -> None:
        if self._server is None:
            return
        for connection in list(self._server.active_connections.values()):
            connection.close()


def _exception_code(code: Any) -> ExcCodes:
    try:
        return ExcCodes(int(code))
    except ValueError:
        log.warning("modbus_exception fault: unknown code %r, answering DEVICE_FAILURE", code)
        return ExcCodes.DEVICE_FAILURE


class SimulatedWatlowF4(_SimulatedModbusChamber):
    """Series F4 speaking Modbus RTU frames over TCP (like an RS-485-to-Ethernet gateway).

    ``address`` is ``socket://127.0.0.1:PORT``, the form :class:`WatlowF4` takes.
    """

    MODEL = "Watlow F4"
    FRAMER = FramerType.RTU
    #: the registers of the driver's map, plus digital input 1 where the simulated limit
    #: controller is wired (station sim.yaml: chamber.limit_input: 1)
    REGISTERS = {**F4_REGISTERS, **{r.name: r for r in digital_input_registers(1)}}
    #: the input triggers on a high state (condition 1061 = 1; F4P manual p. 9.4): the limit
    #: controller's contact reads low (201 = 0) while healthy and high (201 = 1) once tripped
    LIMIT_INPUT_CONDITION = 1
    SERIAL_NUMBER = (12, 3456)

    def __init__(
        self,
        physics: ChamberPhysics,
        faults: FaultInjector | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        unit_id: int = 1,
        decimals: int = 1,
    ) -> None:
        super().__init__(physics, faults, host, port, unit_id)
        self.decimals = decimals

    @property
    def address(self) -> str:
        return f"socket://{self.host}:{self.bound_port}"

    def _decimals(self) -> int:
        return self.decimals

    def _value(self, register: Register) -> float | int | str:
        name = register.name
        if name == "model":
            return F4_MODEL_NUMBER
        if name == "serial_high":
            return self.SERIAL_NUMBER[0]
        if name == "serial_low":
            return self.SERIAL_NUMBER[1]
        if name == "process_value":
            return self.physics.temperature_c()
        if name == "setpoint":
            return self.physics.setpoint_c
        if name == "input1_decimals":
            return self.decimals
        if name == "temperature_units":
            return 1                  # °C (nonzero); the F4's factory default is not documented here
        if name == "profile_state":
            return 2 if self.faults.params("profile_running") is not None else 0
        if name == "di1_state":       # active (= its condition) only while the limit is tripped
            tripped = self._alarm_forced() or self.physics.alarm_state().active
            return self.LIMIT_INPUT_CONDITION if tripped else 1 - self.LIMIT_INPUT_CONDITION
        if name == "di1_condition":
            return self.LIMIT_INPUT_CONDITION
        raise KeyError(name)


class SimulatedWatlowF4T(_SimulatedModbusChamber):
    """F4T speaking Modbus TCP. ``address`` is ``127.0.0.1:PORT``, the form :class:`WatlowF4T` takes."""

    MODEL = "Watlow F4T"
    FRAMER = FramerType.SOCKET
    REGISTERS = F4T_REGISTERS
    PART_NUMBER = "F4T1L0AA1A1AAA1"
    SERIAL_NUMBER = 1234567
    SOFTWARE_RELEASE = 7
    #: as shipped: Display Units F (30) — the guide's factory default — so temperatures and
    #: set points on Modbus are °F until someone changes it on the front panel
    display_units = DISPLAY_UNITS_F

    def _in_units(self, celsius: float) -> float:
        return celsius * 1.8 + 32.0 if self.display_units == DISPLAY_UNITS_F else celsius

    def _apply_write(self, register: Register, value: Any) -> None:
        """Set point in the display units; the display units themselves (F 30 / C 15)."""
        if register.name == "display_units":
            if int(value) not in (DISPLAY_UNITS_F, DISPLAY_UNITS_C):
                raise ValueError(f"display units {value!r}: F (30) or C (15)")
            self.display_units = int(value)
            return
        if register.name == "setpoint" and self.display_units == DISPLAY_UNITS_F:
            value = (float(value) - 32.0) / 1.8
        super()._apply_write(register, value)

    @property
    def address(self) -> str:
        return f"{self.host}:{self.bound_port}"

    def _value(self, register: Register) -> float | int | str:
        name = register.name
        if name == "software_release":
            return self.SOFTWARE_RELEASE
        if name == "serial_number":
            return self.SERIAL_NUMBER
        if name == "part_number":
            return self.PART_NUMBER
        if name == "device_status":
            return DEVICE_STATUS_OK
        if name == "display_units":
            return self.display_units
        if name == "process_value":
            return self._in_units(self.physics.temperature_c())
        if name == "setpoint":
            return self._in_units(self.physics.setpoint_c)
        if name == "profile_state":
            running = self.faults.params("profile_running") is not None
            return PROFILE_STATE_RUNNING if running else ALARM_STATE_NONE    # 61 "none"
        if name == "alarm1_state":
            forced = self.faults.params("alarm")
            if forced is not None:
                return int(forced.get("state", ALARM_STATE_HIGH))
            if self.physics.alarm_state().active:
                above = self.physics.true_temperature_c() > self.physics.setpoint_c
                return ALARM_STATE_HIGH if above else ALARM_STATE_LOW
            return ALARM_STATE_NONE
        raise KeyError(name)

