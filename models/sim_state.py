"""A simulator's state as plain JSON data, so a resumed dry run continues where it was cut.

A dry run is exact only if the state the simulated station was in when a
step began can be had again after a kill: the air temperature the chamber
was on its way to, the table's motion, the gyro's noise filters, Markov and
walk levels, thermal lag and hysteresis branch, the random streams between
attempts, the frame grid. A class that keeps such state names the
attributes that hold it in ``SIM_STATE``; :func:`capture` turns them into
JSON values (journaled by the run) and :func:`restore` writes them back into
a live object of the same class, in place, so every server and driver that
holds a reference to it sees the restored state.

What the codec knows, and nothing else (a snapshot is data, never code):
numbers, strings, None, NumPy arrays of booleans/integers/floats (exact:
floats are written with ``repr``, which round-trips), NumPy random
generators (their bit generator's state; PCG64's as one text), lists, tuples, deques and dicts
of those, frozen dataclasses defined in gyrocal's own modules, and objects
that themselves declare ``SIM_STATE`` (restored into the live object found
at the same place). A class may instead define ``sim_state()`` and
``restore_sim_state(state)`` (the chamber and the table keep only their
recent history that way).
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from collections import deque
from typing import Any

import numpy as np

#: how much of a chamber's or table's history a snapshot keeps (seconds before now): a
#: simulated gyro asks for the physics at most a block of frames behind the clock
SIM_HISTORY_S = 60.0
#: modules whose dataclasses a snapshot may name (and so construct)
_OWN_PREFIX = "gyrocal."


class SimStateError(ValueError):
    """A snapshot that does not fit the live object (a different model, station or version)."""


def capture(obj: Any) -> dict[str, Any]:
    """The state ``obj`` declares (``SIM_STATE`` or ``sim_state()``), as JSON data."""
    custom = getattr(obj, "sim_state", None)
    if callable(custom):
        return {"class": _name(type(obj)), "custom": custom()}
    names = _declared(obj)
    return {"class": _name(type(obj)),
            "attrs": {name: encode(getattr(obj, name)) for name in names}}


def restore(obj: Any, state: dict[str, Any]) -> None:
    """Write ``state`` (from :func:`capture` on an object of the same class) into ``obj``."""
    if not isinstance(state, dict) or state.get("class") != _name(type(obj)):
        raise SimStateError(f"snapshot of {_field(state, 'class')} cannot restore a "
                            f"{_name(type(obj))}")
    if "custom" in state:
        obj.restore_sim_state(state["custom"])
        return
    attrs = state.get("attrs")
    names = _declared(obj)
    if not isinstance(attrs, dict) or set(attrs) != set(names):
        raise SimStateError(f"snapshot of {_name(type(obj))} holds {sorted(attrs or {})}, "
                            f"expected {sorted(names)}")
    for name in names:
        setattr(obj, name, decode(attrs[name], getattr(obj, name)))


def encode(value: Any) -> Any:
    """One value as JSON data (see the module docstring for what is known)."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, np.bool_):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else {"float": repr(number)}
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise SimStateError(f"array of dtype {value.dtype} is not simulator state")
        return {"array": value.dtype.str, "shape": list(value.shape),
                "values": [encode(v) for v in value.reshape(-1).tolist()]}
    if isinstance(value, np.random.Generator):
        return _encode_generator(value)
    if isinstance(value, deque):
        return {"deque": [encode(v) for v in value], "maxlen": value.maxlen}
    if isinstance(value, (list, tuple)):
        return {type(value).__name__: [encode(v) for v in value]}
    if isinstance(value, dict):
        return {"dict": [[encode(k), encode(v)] for k, v in value.items()]}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"dataclass": _name(type(value)),
                "fields": {f.name: encode(getattr(value, f.name))
                           for f in dataclasses.fields(value)}}
    if hasattr(value, "SIM_STATE") or callable(getattr(value, "sim_state", None)):
        return {"object": capture(value)}
    raise SimStateError(f"{_name(type(value))} is not simulator state the codec knows")


def decode(data: Any, live: Any = None) -> Any:
    """The value ``data`` encodes; objects are restored into ``live`` (the current value)."""
    if data is None or isinstance(data, (bool, str, int, float)):
        return _scalar_like(data, live)
    if not isinstance(data, dict) or len(data) == 0:
        raise SimStateError(f"not simulator state: {data!r:.80}")
    if "float" in data:
        return float(data["float"])
    if "array" in data:
        flat = [decode(v) for v in data["values"]]
        return np.array(flat, dtype=np.dtype(data["array"])).reshape(data["shape"])
    if "pcg64" in data:
        generator = live if isinstance(live, np.random.Generator) else np.random.default_rng()
        generator.bit_generator.state = _pcg64_state(data["pcg64"])
        return generator
    if "rng" in data:       # every generator's state, as snapshots were first written
        generator = live if isinstance(live, np.random.Generator) else np.random.default_rng()
        generator.bit_generator.state = _wide_ints(data["rng"], _unhex)
        return generator
    if "deque" in data:
        return deque((decode(v) for v in data["deque"]), maxlen=data["maxlen"])
    if "list" in data or "tuple" in data:
        items = data.get("list", data.get("tuple"))
        lives = list(live) if isinstance(live, (list, tuple)) and len(live) == len(items) else []
        out = [decode(v, lives[i] if lives else None) for i, v in enumerate(items)]
        return out if "list" in data else tuple(out)
    if "dict" in data:
        current = live if isinstance(live, dict) else {}
        pairs = [(decode(k), v) for k, v in data["dict"]]
        return {key: decode(v, current.get(key)) for key, v in pairs}
    if "dataclass" in data:
        cls = _own_dataclass(data["dataclass"])
        return cls(**{name: decode(v) for name, v in data["fields"].items()})
    if "object" in data:
        if live is None:
            raise SimStateError(f"no live {_field(data['object'], 'class')} to restore into")
        restore(live, data["object"])
        return live
    raise SimStateError(f"not simulator state: {sorted(data)}")


def _encode_generator(generator: np.random.Generator) -> dict[str, Any]:
    """A generator's bit generator state; NumPy's default (PCG64) as one text
    ``"state/increment/has_uint32/uinteger"`` (128-bit words in hex).

    An IMU's snapshot holds ~70 generators (the flicker bank draws a stream per
    process, per axis): as nested objects they made 26 kB of each ``step_completed``
    line and ~0.7 s of an IMU dry run's journal encoding (sorted keys), against
    ~0.1 s for the text form. Snapshots in the nested form (``"rng"``) still restore.
    """
    state = generator.bit_generator.state
    if state.get("bit_generator") != "PCG64":
        return {"rng": _wide_ints(state, _hex)}
    words = state["state"]
    return {"pcg64": f"{words['state']:x}/{words['inc']:x}/{state['has_uint32']}/{state['uinteger']}"}


def _pcg64_state(text: Any) -> dict[str, Any]:
    """The PCG64 state a ``"pcg64"`` text holds (:func:`_encode_generator`)."""
    parts = text.split("/") if isinstance(text, str) else []
    try:
        state, inc, has_uint32, uinteger = (int(part, 16 if i < 2 else 10)
                                            for i, part in enumerate(parts))
    except ValueError:
        raise SimStateError(f"not a PCG64 state: {text!r:.80}") from None
    return {"bit_generator": "PCG64", "state": {"state": state, "inc": inc},
            "has_uint32": has_uint32, "uinteger": uinteger}


def _wide_ints(value: Any, convert) -> Any:
    """A bit generator's state with its 128-bit words through ``convert`` (JSON readers
    other than Python's keep 53 bits of an integer, so they are written as hex text)."""
    if isinstance(value, dict) and "hex" not in value:
        return {key: _wide_ints(item, convert) for key, item in value.items()}
    return convert(value)


def _hex(value: Any) -> Any:
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 2**53:
        return {"hex": hex(value)}
    return value


def _unhex(value: Any) -> Any:
    return int(value["hex"], 16) if isinstance(value, dict) and "hex" in value else value


def _scalar_like(value: Any, live: Any) -> Any:
    """Keep an int that was a float a float (JSON writes 2.0 as 2.0, but be strict)."""
    if isinstance(live, (float, np.floating)) and isinstance(value, int) and \
            not isinstance(value, bool):
        return float(value)
    return value


def _declared(obj: Any) -> tuple[str, ...]:
    names = getattr(type(obj), "SIM_STATE", None)
    if names is None:
        raise SimStateError(f"{_name(type(obj))} declares no SIM_STATE")
    return tuple(names)


def _own_dataclass(name: str) -> type:
    module, _, qualname = str(name).partition(":")
    if not module.startswith(_OWN_PREFIX):
        raise SimStateError(f"snapshot names {name!r}, not one of gyrocal's dataclasses")
    target: Any = importlib.import_module(module)
    for part in qualname.split("."):
        target = getattr(target, part, None)
    if not (isinstance(target, type) and dataclasses.is_dataclass(target)):
        raise SimStateError(f"snapshot names {name!r}, not one of gyrocal's dataclasses")
    return target


def _name(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _field(data: Any, key: str) -> Any:
    return data.get(key) if isinstance(data, dict) else data
