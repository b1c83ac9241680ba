"""What an instrument address reaches, spelled one way: the keys of the station locks.

A lock keyed on the address as written lets a second controller in by another
spelling of the same instrument (``localhost:5020`` for ``127.0.0.1:5020``,
``/dev/serial/by-id/usb-…`` for ``/dev/ttyUSB0``) — two programs commanding one
table (issue 28). So an address becomes the set of endpoints it reaches:

* a TCP endpoint (``host:port``, ``socket://host:port``, a VISA
  ``TCPIP0::host::port::SOCKET``): ``tcp:IP:PORT`` for every address the host
  name resolves to, with every loopback address (127.0.0.0/8, ::1) as one
  ``tcp:loopback:PORT`` — a server on this machine answers on all of them;
* a device (``/dev/ttyUSB0``, a VISA ``ASRL/dev/ttyS0::INSTR``, a pty): its real
  path after every symbolic link, ``dev:/dev/ttyUSB0``.

Two addresses conflict when their key sets meet. A host name that does not
resolve keys on the name itself (lower case): nothing can connect to it either.
"""

from __future__ import annotations

import ipaddress
import os
import re
import socket

#: The port a bare host means, per role (the F4T's Modbus TCP port).
DEFAULT_TCP_PORT = {"chamber": 502, "table": 5025}

_VISA_SOCKET = re.compile(r"TCPIP\d*::(?P<host>[^:]+|\[[^\]]+\])::(?P<port>\d+)::SOCKET", re.I)
_VISA_SERIAL = re.compile(r"ASRL(?P<device>/[^:]+)::INSTR", re.I)
_URL = re.compile(r"(?P<scheme>socket|rfc2217)://(?P<host>\[[^\]]+\]|[^:/]+):(?P<port>\d+)", re.I)
_HOST_PORT = re.compile(r"(?P<host>\[[^\]]+\]|[^:/\s]+)(?::(?P<port>\d+))?")


def instrument_keys(role: str, address: str) -> tuple[str, ...]:
    """The lock keys of the instrument ``address`` reaches (sorted, never empty)."""
    text = address.strip()
    for pattern in (_VISA_SOCKET, _URL):
        match = pattern.fullmatch(text)
        if match:
            return _tcp_keys(match["host"], int(match["port"]))
    match = _VISA_SERIAL.fullmatch(text)
    if match:
        return (_device_key(match["device"]),)
    if text.startswith("/") or os.sep in text:
        return (_device_key(text),)
    match = _HOST_PORT.fullmatch(text)
    if match and (match["port"] or role in DEFAULT_TCP_PORT):
        port = int(match["port"]) if match["port"] else DEFAULT_TCP_PORT[role]
        return _tcp_keys(match["host"], port)
    return (f"name:{text.lower()}",)       # COM3, loop://, a VISA alias: as written


def _device_key(path: str) -> str:
    return f"dev:{os.path.realpath(path)}"


def _tcp_keys(host: str, port: int) -> tuple[str, ...]:
    host = host.strip("[]")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError):
        return (f"tcp:{host.lower()}:{port}",)
    keys = set()
    for *_, sockaddr in infos:
        ip = ipaddress.ip_address(str(sockaddr[0]).split("%")[0])
        keys.add(f"tcp:loopback:{port}" if ip.is_loopback else f"tcp:{ip.compressed}:{port}")
    return tuple(sorted(keys)) or (f"tcp:{host.lower()}:{port}",)
