"""pymodbus's own TCP server over a plain holding-register block: a Modbus peer that is not ours.

No project code is behind it: tests fill its registers by hand from the
manuals, so a mistake shared by a driver and the project's simulator shows.
"""

from __future__ import annotations

import asyncio
import threading

from pymodbus.client import ModbusTcpClient
from pymodbus.datastore import ModbusDeviceContext, ModbusSequentialDataBlock, ModbusServerContext
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer


class StockServer:
    """pymodbus's own TCP server over a sequential holding-register block, in a thread."""

    def __init__(self, registers: dict[int, int], framer: FramerType) -> None:
        # pymodbus 3.16's sequential block: block address 1 is protocol address 0
        self.values = [0] * 20000
        for address, value in registers.items():
            self.values[address] = value
        self.block = ModbusSequentialDataBlock(1, self.values)
        self.context = ModbusServerContext(devices=ModbusDeviceContext(hr=self.block), single=True)
        self.framer = framer
        self.port = 0
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)

        async def start() -> None:
            self.server = ModbusTcpServer(self.context, framer=self.framer,
                                          address=("127.0.0.1", 0))
            await self.server.serve_forever(background=True)
            self.port = self.server.transport.sockets[0].getsockname()[1]
            self._ready.set()
        self._loop.run_until_complete(start())
        self._loop.run_forever()

    def __enter__(self) -> StockServer:
        self._thread.start()
        assert self._ready.wait(10)
        return self

    def __exit__(self, *exc: object) -> None:
        asyncio.run_coroutine_threadsafe(self.server.shutdown(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)

    # The server keeps its own copy of the block once started: look and change through
    # pymodbus's own client (framed like the server), never through the driver under test.
    def _client(self) -> ModbusTcpClient:
        return ModbusTcpClient("127.0.0.1", port=self.port, framer=self.framer, timeout=2,
                               retries=0)

    def hr(self, address: int, count: int = 1) -> list[int]:
        client = self._client()
        try:
            return list(client.read_holding_registers(address, count=count, device_id=1).registers)
        finally:
            client.close()

    def set(self, address: int, values: list[int]) -> None:
        client = self._client()
        try:
            assert not client.write_registers(address, values, device_id=1).isError()
        finally:
            client.close()
