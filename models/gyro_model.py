"""Gyro model files: the YAML contract of ``gyro-model.md`` as frozen dataclasses.

A model file is written by people and by the discrepancy workflow and read
by the simulator and the analysis, so every mistake must be caught at load
time with a message that points at the file, the line and the key path
(``gyro-models/x.yaml:12: effects[1].tau_s: must be > 0, got -5``) rather
than surfacing hours into an overnight run.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import yaml

from gyrocal.errors import BadInput
from gyrocal.inputs import InputError, KeyPath, Location, YamlDocument, load_yaml
from gyrocal.models.effects import EFFECTS, ParamDef
from gyrocal.problems import sort_problems
from gyrocal.schema import Context, Fields
from gyrocal.units import UnitError

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
_NOISE_KEYS = tuple(f.name for f in fields(NoiseParams))


# --------------------------------------------------------------------------- parsing
#
# Read with the one schema reader of the input languages (``Context`` collects every
# problem at its file, line and key path; ``Fields`` takes a mapping key by key and
# names unknown keys), as procedures and stations are. The converters below are the
# model language's own rules: finite numbers within ±MAX_MAGNITUDE, effect parameters
# checked against the catalogue.


#: Bound on every number of a model file. Beyond it nothing is physical (an ARW of
#: 1e+308 deg/√h overflowed the simulator), and squares and fourth powers of the
#: noise terms stay far inside float64.
MAX_MAGNITUDE = 1e9


class _DataDocument(YamlDocument):
    """A model given as data (by code, or by a caller that kept only some line numbers):
    a path without a recorded line is shown without one rather than as line 1."""

    def where(self, path: KeyPath) -> Location:
        for end in range(len(path), -1, -1):
            found = self.locations.get(tuple(path[:end]))
            if found is not None:
                return found
        return Location(self.file, None)  # type: ignore[arg-type]


def data_context(source: str, lines: Mapping[tuple, int] | None = None) -> Context:
    """A reading context for plain data named ``source``, with the line of each key path."""
    locations = {tuple(key): Location(source, line) for key, line in (lines or {}).items()}
    return Context(_DataDocument(file=source, path=Path(source), data=None, locations=locations))


def raise_problems(ctx: Context, before: int = 0) -> None:
    """One :class:`ModelError` listing every problem found since ``before``, in file order."""
    found = ctx.problems[before:]
    if found:
        raise ModelError("\n".join(str(p) for p in sort_problems(found)))


def model_number(value: object) -> float:
    """A finite number within ±MAX_MAGNITUDE; YAML ``true`` is not 1."""
    # bool is an int subclass: `true` in YAML must not silently become 1.0.
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UnitError(f"must be a number, got {type(value).__name__} {value!r}")
    try:
        number = float(value)
    except OverflowError:          # a YAML integer beyond float range
        raise UnitError(f"must be a finite number, got {value!r}") from None
    if not math.isfinite(number):
        raise UnitError(f"must be a finite number, got {value!r}")
    if abs(number) > MAX_MAGNITUDE:
        raise UnitError(f"{number:g} is beyond ±{MAX_MAGNITUDE:g}: no gyro quantity in a "
                        "model file is that large (a unit or exponent slip?)")
    return number


def non_negative(value: object) -> float:
    number = model_number(value)
    if number < 0:
        raise UnitError(f"must be >= 0, got {number:g}")
    return number


def _version(single_axis: bool) -> Callable[[object], int]:
    def convert(value: object) -> int:
        if value == 2 and single_axis:
            raise UnitError("unsupported version 2 for a single-axis model: version 2 is a "
                            "three-axis IMU model (axes:, misalignment_urad:); this use takes a "
                            "version 1 model")
        if isinstance(value, bool) or not isinstance(value, int):
            raise UnitError(f"must be an integer, got {value!r}")
        if value not in SUPPORTED_VERSIONS:
            raise UnitError(f"unsupported version {value}; supported: {SUPPORTED_VERSIONS}")
        return value
    return convert


def _scale_factor(value: object) -> float:
    number = model_number(value)
    if number == 0:
        raise UnitError("must be non-zero")
    return number


def _name(value: object) -> str:
    if value is None:
        return ""
    if not isinstance(value, str):
        raise UnitError(f"must be a string, got {type(value).__name__}")
    return value


def output_units(value: object) -> str:
    if value not in OUTPUT_UNITS:
        raise UnitError(f"must be one of {', '.join(OUTPUT_UNITS)}, got {value!r}")
    return str(value)


def _effect_name(value: object) -> str:
    if not isinstance(value, str) or value not in EFFECTS:
        raise UnitError(f"unknown effect {value!r}; known effects: {', '.join(EFFECTS)}")
    return value


def read_noise(ctx: Context, parent: Fields) -> NoiseParams | None:
    present, raw = parent.raw("noise")
    if not present or raw is None:
        return NoiseParams()
    noise = Fields(ctx, parent.child("noise"), raw, "noise")
    values = {key: noise.take(key, non_negative, required=False, default=0.0)
              for key in _NOISE_KEYS}
    noise.finish()
    if not noise.valid or None in values.values():
        return None
    return NoiseParams(**values)


def read_effect(ctx: Context, path: KeyPath, raw: object) -> EffectSpec | None:
    """One catalogue effect with every parameter of its definition, each within its bounds."""
    entry = Fields(ctx, path, raw, "an effect")
    if not entry.valid:
        return None
    name = entry.take("name", _effect_name)
    if name is None:
        entry.used.update(entry.data)   # unknown effect: its keys cannot be judged
        return None
    definition = EFFECTS[name]
    params: dict[str, float | None] = {}
    for p in definition.params:
        if not entry.has(p.key):
            entry.used.add(p.key)
            ctx.report(entry.child(p.key), f"missing parameter of effect {name!r} "
                       f"({p.unit}, {p.constraint})")
            params[p.key] = None
            continue

        def checked(value: object, param: ParamDef = p) -> float:
            number = model_number(value)
            problem = param.check(number)
            if problem:
                raise UnitError(problem)
            return number
        params[p.key] = entry.take(p.key, checked)
    entry.finish()
    if None in params.values():
        return None
    return EffectSpec(name, params)  # type: ignore[arg-type]


def read_effects(ctx: Context, parent: Fields) -> tuple[EffectSpec, ...] | None:
    """The ``effects`` list: catalogue effects, each at most once."""
    present, raw = parent.raw("effects")
    if not present or raw is None:
        return ()
    if not isinstance(raw, list):
        ctx.report(parent.child("effects"), f"must be a list, got {type(raw).__name__}")
        return None
    effects: list[EffectSpec] = []
    seen: dict[str, int] = {}
    complete = True
    for index, item in enumerate(raw):
        spec = read_effect(ctx, (*parent.child("effects"), index), item)
        if spec is None:
            complete = False
        elif spec.name in seen:
            ctx.report((*parent.child("effects"), index, "name"),
                       f"effect {spec.name!r} given twice (also effects[{seen[spec.name]}])")
            complete = False
        else:
            seen[spec.name] = index
            effects.append(spec)
    return tuple(effects) if complete else None


def read_model(ctx: Context, path: KeyPath, data: object) -> GyroModel | None:
    """A single-axis model at ``path`` of the document (``()``, or one axis of an IMU file);
    None when anything was wrong (every problem is in ``ctx``)."""
    if data is None:
        ctx.report(path, "empty model (version and scale_factor are required)")
        return None
    top = Fields(ctx, path, data, "a model")
    if not top.valid:
        return None
    before = len(ctx.problems)
    version = top.take("version", _version(single_axis=not path))
    scale_factor = top.take("scale_factor", _scale_factor)
    name = top.take("name", _name, required=False, default="")
    units = top.take("output_units", output_units, required=False, default="deg/s")
    numbers = {k: top.take(k, model_number, required=False, default=0.0) for k in _NUMBER_KEYS}
    noise = read_noise(ctx, top)
    effects = read_effects(ctx, top)
    top.finish()
    if len(ctx.problems) > before or None in (noise, effects):
        return None
    return GyroModel(version=version, scale_factor=scale_factor, name=name, output_units=units,
                     noise=noise, effects=effects, **numbers)


def _check_effect_spec(effect: EffectSpec) -> EffectSpec:
    """Validate an EffectSpec built in code (the workflow adds effects this way)."""
    ctx = data_context(f"effect {effect.name!r}")
    spec = read_effect(ctx, ("effects", 0), {"name": effect.name, **effect.params})
    raise_problems(ctx)
    assert spec is not None
    return spec


def parse_model(data: Any, source: str = "<model>", lines: dict[tuple, int] | None = None,
                key_prefix: tuple = ()) -> GyroModel:
    """Validate a model given as plain data (as ``yaml.safe_load`` returns it).

    ``source`` names the origin in messages; ``lines`` maps key paths to line
    numbers (``load_model`` supplies them from the yaml node marks);
    ``key_prefix`` is where the model sits inside a larger file (one axis of a
    three-axis model, ``models/imu_model.py``), so messages name the full path.
    """
    ctx = data_context(source, lines)
    model = read_model(ctx, key_prefix, data)
    raise_problems(ctx)
    assert model is not None
    return model


def read_document(path: str | Path) -> YamlDocument:
    """The model file through the one input layer: regular files only, size and nesting
    limits, alias bombs and duplicate keys refused; a file that cannot be read at all
    says so in the model's words."""
    try:
        return load_yaml(path)
    except InputError as exc:
        raise ModelError("\n".join(
            f"{p.file}: cannot read model file: {p.message}" if p.line is None and not p.path
            else str(p) for p in exc.problems)) from None


def load_model(path: str | Path) -> GyroModel:
    """Read and validate a model file; every error names the file, line and key path."""
    document = read_document(path)
    ctx = Context(document)
    model = read_model(ctx, (), document.data)
    raise_problems(ctx)
    assert model is not None
    return model


# --------------------------------------------------------------------------- writing


def model_to_dict(model: GyroModel) -> dict:
    """Plain data in the file layout (key order of the spec); parse_model round-trips it."""
    data: dict[str, Any] = {
        "version": model.version,
        "name": model.name,
        "output_units": model.output_units,
        "scale_factor": model.scale_factor,
    }
    values = asdict(model)      # typed fields by name: the file's keys are the field names
    data.update({key: values[key] for key in _NUMBER_KEYS})
    data["noise"] = asdict(model.noise)
    data["effects"] = [
        {"name": e.name, **{k: e.params[k] for k in EFFECTS[e.name].keys}} for e in model.effects
    ]
    return data


def dump_model(model: GyroModel, path: str | Path) -> None:
    """Write a model file that ``load_model`` reads back to an equal model."""
    text = yaml.safe_dump(model_to_dict(model), sort_keys=False, default_flow_style=False)
    Path(path).write_text(text, encoding="utf-8")
