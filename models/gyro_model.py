"""Gyro model files: the YAML contract of ``gyro-model.md`` as frozen dataclasses.

A model file is written by people and by the discrepancy workflow and read
by the simulator and the analysis, so every mistake must be caught at load
time with a message that points at the file, the line and the key path
(``gyro-models/x.yaml:12: effects[1].tau_s: must be > 0, got -5``) rather
than surfacing hours into an overnight run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import yaml

from gyrocal.errors import BadInput
from gyrocal.inputs import InputError, format_key_path, load_yaml
from gyrocal.models.effects import EFFECTS

SUPPORTED_VERSIONS = (1,)
OUTPUT_UNITS = ("deg/s", "deg/h", "rad/s", "V", "LSB")


class ModelError(BadInput, ValueError):
    """A model file or dict that breaks the contract; the message names where."""


@dataclass(frozen=True)
class NoiseParams:
    """IEEE Std 952 noise coefficients of the rate noise w(t), in the spec's units."""

    quantization_arcsec: float = 0.0   # Q
    arw_deg_per_rth: float = 0.0       # N
    bias_instability_dph: float = 0.0  # B
    rrw_deg_per_h_rth: float = 0.0     # K
    rate_ramp_dph_per_h: float = 0.0   # R


@dataclass(frozen=True)
class EffectSpec:
    """One catalogue effect in a model, with all its parameters (keys as in the catalogue)."""

    name: str
    params: dict[str, float] = field(default_factory=dict)

    def __getitem__(self, key: str) -> float:
        return self.params[key]


@dataclass(frozen=True)
class GyroModel:
    """The measurement model. Left-out keys are 0 / no effect, as the contract says."""

    version: int
    scale_factor: float
    name: str = ""
    output_units: str = "deg/s"
    reference_temp_c: float = 0.0
    bias_dph: float = 0.0
    bias_tempco_dph_per_c: float = 0.0
    sf_error_ppm: float = 0.0
    sf_tempco_ppm_per_c: float = 0.0
    earth_rate_dph: float = 0.0
    noise: NoiseParams = field(default_factory=NoiseParams)
    effects: tuple[EffectSpec, ...] = ()

    def effect(self, name: str) -> EffectSpec | None:
        """The model's entry for catalogue effect ``name``, or None."""
        for e in self.effects:
            if e.name == name:
                return e
        return None

    def has_effect(self, name: str) -> bool:
        return self.effect(name) is not None

    def without_effect(self, name: str) -> GyroModel:
        """The same model minus one effect (used to isolate an effect's signature)."""
        return replace(self, effects=tuple(e for e in self.effects if e.name != name))

    def with_effect(self, effect: EffectSpec) -> GyroModel:
        """The same model with ``effect`` added, or replacing the entry of the same name."""
        spec = _check_effect_spec(effect)
        kept = [e for e in self.effects if e.name != effect.name]
        return replace(self, effects=(*kept, spec))


_NUMBER_KEYS = (
    "reference_temp_c",
    "bias_dph",
    "bias_tempco_dph_per_c",
    "sf_error_ppm",
    "sf_tempco_ppm_per_c",
    "earth_rate_dph",
)
_TOP_KEYS = ("version", "name", "output_units", "scale_factor", *_NUMBER_KEYS, "noise", "effects")
_NOISE_KEYS = tuple(f.name for f in fields(NoiseParams))


# --------------------------------------------------------------------------- parsing


class _Where:
    """Builds ``file:line: key.path: message`` using the line numbers yaml recorded."""

    def __init__(self, source: str, lines: dict[tuple, int] | None = None,
                 prefix: tuple = ()) -> None:
        self.source = source
        self.lines = lines or {}
        self.prefix = prefix    # where this model sits in a larger file (an IMU axis: axes.x)

    def error(self, path: tuple, message: str) -> ModelError:
        path = (*self.prefix, *path)
        line = None
        probe = path
        while line is None and probe:
            line = self.lines.get(probe)
            probe = probe[:-1]
        if line is None:
            line = self.lines.get(())
        where = f"{self.source}:{line}" if line is not None else self.source
        key = format_key_path(path)
        return ModelError(f"{where}: {key}: {message}" if key else f"{where}: {message}")


#: Bound on every number of a model file. Beyond it nothing is physical (an ARW of
#: 1e+308 deg/√h overflowed the simulator), and squares and fourth powers of the
#: noise terms stay far inside float64.
MAX_MAGNITUDE = 1e9


def _number(value: Any, path: tuple, where: _Where) -> float:
    # bool is an int subclass: `true` in YAML must not silently become 1.0.
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise where.error(path, f"must be a number, got {type(value).__name__} {value!r}")
    try:
        number = float(value)
    except OverflowError:          # a YAML integer beyond float range
        raise where.error(path, f"must be a finite number, got {value!r}") from None
    if not math.isfinite(number):
        raise where.error(path, f"must be a finite number, got {value!r}")
    if abs(number) > MAX_MAGNITUDE:
        raise where.error(path, f"{number:g} is beyond ±{MAX_MAGNITUDE:g}: no gyro quantity in a "
                                "model file is that large (a unit or exponent slip?)")
    return number


def _mapping(value: Any, path: tuple, where: _Where) -> Mapping:
    if not isinstance(value, Mapping):
        raise where.error(path, f"must be a mapping, got {type(value).__name__}")
    return value


def _reject_unknown(data: Mapping, known: tuple[str, ...], path: tuple, where: _Where) -> None:
    for key in data:
        if key not in known:
            raise where.error((*path, key), f"unknown key; known keys: {', '.join(known)}")


def _parse_noise(data: Any, where: _Where) -> NoiseParams:
    if data is None:
        return NoiseParams()
    noise = _mapping(data, ("noise",), where)
    _reject_unknown(noise, _NOISE_KEYS, ("noise",), where)
    values = {}
    for key, raw in noise.items():
        number = _number(raw, ("noise", key), where)
        if number < 0:
            raise where.error(("noise", key), f"must be >= 0, got {number:g}")
        values[key] = number
    return NoiseParams(**values)


def _parse_effect(raw: Any, index: int, where: _Where) -> EffectSpec:
    path: tuple = ("effects", index)
    entry = _mapping(raw, path, where)
    if "name" not in entry:
        raise where.error(path, "missing key 'name'")
    name = entry["name"]
    if not isinstance(name, str) or name not in EFFECTS:
        raise where.error(
            (*path, "name"), f"unknown effect {name!r}; known effects: {', '.join(EFFECTS)}"
        )
    definition = EFFECTS[name]
    _reject_unknown(entry, ("name", *definition.keys), path, where)
    params: dict[str, float] = {}
    for p in definition.params:
        if p.key not in entry:
            raise where.error(
                (*path, p.key), f"missing parameter of effect {name!r} ({p.unit}, {p.constraint})"
            )
        number = _number(entry[p.key], (*path, p.key), where)
        problem = p.check(number)
        if problem:
            raise where.error((*path, p.key), problem)
        params[p.key] = number
    return EffectSpec(name, params)


def _check_effect_spec(effect: EffectSpec) -> EffectSpec:
    """Validate an EffectSpec built in code (the workflow adds effects this way)."""
    data = {"name": effect.name, **effect.params}
    return _parse_effect(data, 0, _Where(f"effect {effect.name!r}"))


def parse_model(data: Any, source: str = "<model>", lines: dict[tuple, int] | None = None,
                key_prefix: tuple = ()) -> GyroModel:
    """Validate a model given as plain data (as ``yaml.safe_load`` returns it).

    ``source`` names the origin in messages; ``lines`` maps key paths to line
    numbers (``load_model`` supplies it from the yaml node marks);
    ``key_prefix`` is where the model sits inside a larger file (one axis of a
    three-axis model, ``models/imu_model.py``), so messages name the full path.
    """
    where = _Where(source, lines, key_prefix)
    if data is None:
        raise where.error((), "empty model (version and scale_factor are required)")
    top = _mapping(data, (), where)
    if top.get("version") == 2 and not key_prefix:
        raise where.error(("version",), "unsupported version 2 for a single-axis model: "
                          "version 2 is a three-axis IMU model (axes:, misalignment_urad:); "
                          "this use takes a version 1 model")
    _reject_unknown(top, _TOP_KEYS, (), where)
    for required in ("version", "scale_factor"):
        if required not in top:
            raise where.error((required,), "missing required key")

    version = top["version"]
    if isinstance(version, bool) or not isinstance(version, int):
        raise where.error(("version",), f"must be an integer, got {version!r}")
    if version not in SUPPORTED_VERSIONS:
        raise where.error(("version",), f"unsupported version {version}; supported: {SUPPORTED_VERSIONS}")

    scale_factor = _number(top["scale_factor"], ("scale_factor",), where)
    if scale_factor == 0:
        raise where.error(("scale_factor",), "must be non-zero")

    name = top.get("name", "")
    if name is None:
        name = ""
    if not isinstance(name, str):
        raise where.error(("name",), f"must be a string, got {type(name).__name__}")
    units = top.get("output_units", "deg/s")
    if units not in OUTPUT_UNITS:
        raise where.error(("output_units",), f"must be one of {', '.join(OUTPUT_UNITS)}, got {units!r}")

    numbers = {k: _number(top[k], (k,), where) for k in _NUMBER_KEYS if k in top}

    raw_effects = top.get("effects") or []
    if not isinstance(raw_effects, list):
        raise where.error(("effects",), f"must be a list, got {type(raw_effects).__name__}")
    effects: list[EffectSpec] = []
    seen: dict[str, int] = {}
    for i, raw in enumerate(raw_effects):
        spec = _parse_effect(raw, i, where)
        if spec.name in seen:
            raise where.error(
                ("effects", i, "name"), f"effect {spec.name!r} given twice (also effects[{seen[spec.name]}])"
            )
        seen[spec.name] = i
        effects.append(spec)

    return GyroModel(
        version=version,
        scale_factor=scale_factor,
        name=name,
        output_units=units,
        noise=_parse_noise(top.get("noise"), where),
        effects=tuple(effects),
        **numbers,
    )


def load_model(path: str | Path) -> GyroModel:
    """Read and validate a model file; every error names the file, line and key path.

    Read through the one input layer (``gyrocal.inputs``): regular files only,
    size and nesting limits, alias bombs and duplicate keys refused.
    """
    try:
        document = load_yaml(path)
    except InputError as exc:
        # A file that cannot be read at all (no line) says so in the model's words.
        raise ModelError("\n".join(
            f"{p.file}: cannot read model file: {p.message}" if p.line is None and not p.path
            else str(p) for p in exc.problems)) from None
    lines = {key: location.line for key, location in document.locations.items()}
    return parse_model(document.data, document.file, lines)


# --------------------------------------------------------------------------- writing


def model_to_dict(model: GyroModel) -> dict:
    """Plain data in the file layout (key order of the spec); parse_model round-trips it."""
    data: dict[str, Any] = {
        "version": model.version,
        "name": model.name,
        "output_units": model.output_units,
        "scale_factor": model.scale_factor,
    }
    for key in _NUMBER_KEYS:
        data[key] = getattr(model, key)
    data["noise"] = {key: getattr(model.noise, key) for key in _NOISE_KEYS}
    data["effects"] = [
        {"name": e.name, **{k: e.params[k] for k in EFFECTS[e.name].keys}} for e in model.effects
    ]
    return data


def dump_model(model: GyroModel, path: str | Path) -> None:
    """Write a model file that ``load_model`` reads back to an equal model."""
    text = yaml.safe_dump(model_to_dict(model), sort_keys=False, default_flow_style=False)
    Path(path).write_text(text, encoding="utf-8")
