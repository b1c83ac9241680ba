"""The three YAML languages (procedure, station, gyro model) described once, as data.

The parsers (``procedure/``, ``station.py``, ``models/gyro_model.py``) check
files key by key in code; users need the same facts written down: every key,
whether it is required, its default, the units it accepts and what it means.
This module is that description. ``reference_docs.py`` renders it to the
Markdown reference in ``docs/reference/`` and to JSON Schemas that editors
(yaml-language-server) use to complete and check files, and
``tests/orchestrator/test_languages.py`` holds it against the parsers: for
every mapping, the keys listed here are the keys the parser allows there, so
the description cannot drift from what ``gyrocal validate`` accepts.

Constants are imported from the parsers (drivers, choices, limits, the effect
catalogue, the metrics) rather than copied, for the same reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gyrocal.instruments.driver_spec import DriverSpec, Role, Setting, SettingKind
from gyrocal.instruments.registry import registry
from gyrocal.metrology.metrics import METRICS
from gyrocal.models.effects import EFFECTS
from gyrocal.models.gyro_model import OUTPUT_UNITS as MODEL_OUTPUT_UNITS
from gyrocal.models.imu_model import AXES
from gyrocal.models.noise_terms import NOISE_TERMS
from gyrocal.orchestrator import procedure as proc
from gyrocal.orchestrator import station as sta
from gyrocal.orchestrator.notify import NotifyOn
from gyrocal.units import (
    ACCELERATION,
    DURATION,
    FREQUENCY,
    RATE,
    TEMPERATURE,
    TEMPERATURE_RATE,
    Dimension,
)

# -- the vocabulary ------------------------------------------------------------------------


@dataclass(frozen=True)
class Scalar:
    """A leaf value. ``kind`` says how it is written; the other fields narrow it."""

    kind: str                       # text, serial, integer, number, boolean, date, choice,
    #                                 int_choice, quantity, duration, path, anything, text_list
    dimension: Dimension | None = None
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: float | None = None
    bare_seconds: bool = False      # a duration that also takes a bare number of seconds
    constant: int | None = None     # a version number
    int_choices: tuple[int, ...] = ()   # kind int_choice: one of these whole numbers
    hex_text: bool = False          # an int_choice also written as text ("0x94")


@dataclass(frozen=True)
class Key:
    name: str
    value: Shape
    doc: str
    required: bool = True
    default: str | None = None       # as the reference shows it ("1", "inherited from defaults")


@dataclass(frozen=True)
class Section:
    """A mapping with a fixed set of keys; ``anchor`` names its part of the reference."""

    anchor: str
    title: str
    doc: str
    keys: tuple[Key, ...]
    #: keys outside ``keys`` are allowed (free-form: ``templates``, matrix elements)
    open_keys: Scalar | None = None

    def key(self, name: str) -> Key | None:
        return next((k for k in self.keys if k.name == name), None)


@dataclass(frozen=True)
class ListOf:
    item: Shape
    min_items: int = 1


@dataclass(frozen=True)
class Variants:
    """A mapping whose keys depend on one key's value (``kind:`` of a test, ``name:`` of an
    effect)."""

    discriminator: str
    sections: tuple[tuple[str, Section], ...]


@dataclass(frozen=True)
class Either:
    """One of several shapes (``station:`` is a path or a whole station mapping)."""

    options: tuple[Shape, ...]


Shape = Scalar | Section | ListOf | Variants | Either


@dataclass(frozen=True)
class Language:
    name: str                  # procedure, station, model
    title: str
    intro: str
    root: Shape
    doc_file: str              # docs/reference/<name>.md
    schema_file: str           # docs/schemas/<name>.schema.json
    examples: tuple[str, ...] = field(default_factory=tuple)   # shipped files to quote


def _text() -> Scalar:
    return Scalar("text")


def _q(dimension: Dimension, minimum: float | None = None, *, above: float | None = None,
       maximum: float | None = None) -> Scalar:
    return Scalar("quantity", dimension, minimum=minimum, exclusive_minimum=above, maximum=maximum)


def _duration(*, bare_seconds: bool = False, positive: bool = True) -> Scalar:
    return Scalar("duration", DURATION, bare_seconds=bare_seconds,
                  exclusive_minimum=0.0 if positive else None, minimum=None if positive else 0.0)


def _choice(options: tuple[str, ...] | list[str]) -> Scalar:
    return Scalar("choice", choices=tuple(options))


def _int(minimum: int | None = None, maximum: int | None = None) -> Scalar:
    return Scalar("integer", minimum=minimum, maximum=maximum)


def _num(minimum: float | None = None, maximum: float | None = None, *,
         above: float | None = None) -> Scalar:
    return Scalar("number", minimum=minimum, maximum=maximum, exclusive_minimum=above)


# -- station ---------------------------------------------------------------------------------


def _identity(anchor: str) -> Section:
    return Section(
        anchor, anchor.replace("-", "."),
        "The instrument as the lab's asset register knows it: printed in the report's and the "
        "certificate's traceability. A calibration due before the run's date makes the "
        "verdict BLOCKED unless `calibration_waiver` says why it may pass.",
        (
            Key("make", _text(), "manufacturer"),
            Key("model", _text(), "model"),
            Key("serial", Scalar("serial"), "serial number; a different serial reported by "
                "the instrument itself blocks the verdict"),
            Key("calibration_due", Scalar("date"), "YYYY-MM-DD", False),
            Key("calibration_waiver", _text(), "why an overdue calibration may still PASS "
                "(shown in the report)", False),
            Key("calibration_certificate", Scalar("serial"), "the number of the instrument's "
                "own calibration certificate (named in the traceability)", False),
            Key("calibrated_by", _text(), "who issued that certificate (e.g. an accredited "
                "laboratory)", False),
        ))


_LINK_KEYS = (
    Key("timeout_s", _duration(bare_seconds=True), "per exchange", False, "1 s"),
    Key("retries", _int(0, 20), "retries of a transient fault, with backoff", False, "3"),
)

def _setting_scalar(setting: Setting) -> Scalar:
    if setting.kind is SettingKind.CHOICE:
        if all(isinstance(c, str) for c in setting.choices):
            return _choice(tuple(str(c) for c in setting.choices))
        return Scalar("int_choice", int_choices=tuple(int(c) for c in setting.choices),  # type: ignore[arg-type]
                      hex_text=setting.parse is not None)
    if setting.kind is SettingKind.INTEGER:
        return _int(None if setting.minimum is None else int(setting.minimum),
                    None if setting.maximum is None else int(setting.maximum))
    if setting.kind is SettingKind.NUMBER:
        return _num(setting.minimum, setting.maximum, above=setting.above)
    return Scalar("boolean") if setting.kind is SettingKind.BOOLEAN else _text()


def _driver_keys(role: Role) -> tuple[Key, ...]:
    """The keys of every registered driver of ``role`` (instruments/registry.py), each saying
    which drivers take it: the reference follows the registry, plug-ins included."""
    owners: dict[str, tuple[Setting, list[str]]] = {}
    for spec in registry().for_role(role):
        for setting in spec.settings:
            owners.setdefault(setting.name, (setting, []))[1].append(spec.name)
    everyone = set(registry().names(role))
    keys = []
    for name, (setting, drivers) in owners.items():
        shared = set(drivers) == everyone
        which = " or ".join(drivers)
        scope = "" if shared else f"; applies to driver {which} only"
        if setting.required and not shared:
            scope += f" (required for {which})"
        default = setting.default_text or (None if setting.default is None else str(setting.default))
        keys.append(Key(name, _setting_scalar(setting), (setting.doc or name) + scope,
                        setting.required and shared, default))
    return tuple(keys)


def _drivers_text(role: Role) -> str:
    specs: tuple[DriverSpec, ...] = registry().for_role(role)
    return "; ".join(f"`{s.name}` ({s.summary}: address {s.address.expected})" for s in specs)


STATION_CHAMBER = Section(
    "chamber", "chamber",
    "The temperature chamber. Drivers: " + _drivers_text(Role.CHAMBER) + ". "
    "`sim` as the address: a simulated chamber started by `--sim`.",
    (
        Key("driver", _choice(registry().names(Role.CHAMBER)), "which controller"),
        Key("address", _text(), "where it is (see above), or `sim`"),
        *_driver_keys(Role.CHAMBER),
        Key("identity", _identity("chamber-identity"), "asset identity"),
        Key("limits", Section("chamber-limits", "chamber.limits", "What the chamber may safely "
            "be asked; every procedure run on the station must stay inside.", (
                Key("min_temp_c", _q(TEMPERATURE, -273.15), "lowest setpoint"),
                Key("max_temp_c", _q(TEMPERATURE, -273.15), "highest setpoint"),
                Key("max_ramp_c_per_min", _q(TEMPERATURE_RATE, above=0.0), "fastest ramp"),
            )), "hard limits"),
        Key("safe_state", Section("chamber-safe_state", "chamber.safe_state", "Where the "
            "chamber is left after a fault, Ctrl-C or the end of a run.", (
                Key("action", _choice(("setpoint", "standby")), "hold a setpoint, or standby"),
                Key("setpoint_c", _q(TEMPERATURE), "the safe setpoint (action: setpoint only; "
                    "inside the chamber limits)", False),
            )), "safe state"),
        *_LINK_KEYS,
    ))

STATION_TABLE = Section(
    "table", "table",
    "The rate table. Drivers: " + _drivers_text(Role.TABLE) + ". "
    "`sim` as the address: a simulated table started by `--sim`.",
    (
        Key("driver", _choice(registry().names(Role.TABLE)), "which controller"),
        Key("address", _text(), "a VISA resource string, or `sim`"),
        *_driver_keys(Role.TABLE),
        Key("identity", _identity("table-identity"), "asset identity"),
        Key("limits", Section("table-limits", "table.limits", "What the table may safely do.", (
            Key("max_rate_dps", _q(RATE, above=0.0), "largest rate magnitude"),
            Key("max_accel_dps2", _q(ACCELERATION, above=0.0), "largest acceleration"),
        )), "hard limits"),
        Key("orientation", _choice(sta.TABLE_ORIENTATIONS), "`vertical` (a rate table) or "
            "`horizontal` (turned on its side: in position mode the indexing head that tips the "
            "unit's x axis through gravity, a_x = g·sin θ; the `tilt_linearity` test needs it)",
            False, "vertical"),
        *_LINK_KEYS,
    ))

STATION_GYRO = Section(
    "gyro", "gyro",
    "The unit under test's output. Drivers: " + _drivers_text(Role.GYRO) + ". "
    "`sim`: a simulated gyro started by `--sim`.",
    (
        Key("driver", _choice(registry().names(Role.GYRO)), "which datagram format"),
        Key("port", _text(), "the serial port, or `sim`"),
        Key("sample_rate_hz", _q(FREQUENCY, above=0.0), "the gyro's output rate"),
        Key("timeout_s", _duration(bare_seconds=True), "no datagram for this long is a fault",
            False, "2 s"),
        *_driver_keys(Role.GYRO),
    ))

STATION_SUPPLY = Section(
    "supply", "supply",
    "The programmable supply powering the unit under test (optional). Drivers: "
    + _drivers_text(Role.SUPPLY) + ". The unit is powered at connect, the supply is read "
    "back after every logged step (journal `supply_read`), and an over-current (the unit "
    "drawing the current limit), an output that reads off or a voltage that sags is a fault.",
    (
        Key("driver", _choice(registry().names(Role.SUPPLY)), "which supply"),
        Key("address", _text(), "a VISA resource string, or `sim`"),
        *_driver_keys(Role.SUPPLY),
        Key("identity", _identity("supply-identity"), "asset identity"),
        Key("voltage_v", _num(0.0), "the unit's supply voltage, V"),
        Key("current_limit_a", _num(above=0.0), "the supply's current limit, A; drawing it "
            "is an over-current fault"),
        Key("safe_state", Section("supply-safe_state", "supply.safe_state", "What a fault, "
            "Ctrl-C or the end of a run does with the unit's power (confirmed by read-back).", (
                Key("unit_power", _choice(sta.UNIT_POWER_ACTIONS), "`keep_on` (the unit's "
                    "thermal state is kept for a resume) or `switch_off`"),
            )), "safe state"),
        *_LINK_KEYS,
    ))

STATION_COIL = Section(
    "coil", "coil",
    "A Helmholtz coil for the `magnetic` test kind (optional; needs the `supply` section). A "
    "supply channel is unipolar, so the coil's two polarities are two further channels of "
    "that supply wired in opposition: `positive_channel` gives +B along `axis`, "
    "`negative_channel` -B. Each runs in constant current (its voltage set to "
    "`compliance_v`, its current limit to |B| / `constant_t_per_a`); both are read back and "
    "the field they make must be within 1 % (+0.1 % of the coil's reach) of the set one, "
    "else a fault. Between magnetic steps, at the end of a run and in the safe state both "
    "channels are switched off (read back). On `--sim` the simulated gyro sees the coil "
    "constant × the simulated supply's channel currents along its input axis (`axis: "
    "input`) or nothing (`transverse`).",
    (
        Key("constant_t_per_a", _num(maximum=1.0, above=0.0), "field at the coil's centre per "
            "ampere, T/A (its calibration)"),
        Key("u_constant_rel", _num(0.0, 0.5), "relative standard uncertainty of the coil "
            "constant (a type B line of the sensitivity's budget)", False, "0"),
        Key("axis", _choice(sta.COIL_AXES), "the coil's axis: along the gyro's input axis, or "
            "across it"),
        Key("positive_channel", _int(1, 3), "supply channel driving +B (not `supply.channel`)"),
        Key("negative_channel", _int(1, 3), "supply channel driving -B (another channel)"),
        Key("compliance_v", _num(maximum=100.0, above=0.0), "voltage set on the working "
            "channel, V: above what the coil needs at its maximum current"),
        Key("max_current_a", _num(maximum=100.0, above=0.0), "the coil's rated current, A; a "
            "test's field_t must be within constant_t_per_a × this"),
    ))

SIMULATION = Section(
    "simulation", "simulation",
    "What `--sim` and `gyrocal sim serve` start; ignored on real hardware. Needed when any "
    "address is `sim`.",
    (
        Key("gyro_model", Scalar("path"), "the simulated gyro's model file (relative to this "
            "file; see the model reference)"),
        Key("seed", _int(0), "random seed of the simulated noise", False, "1"),
        Key("chamber", Section("simulation-chamber", "simulation.chamber", "Chamber physics.", (
            Key("ambient_c", _q(TEMPERATURE, -273.15), "room temperature"),
            Key("tau_s", _duration(bare_seconds=True), "air time constant"),
            Key("max_heat_c_per_min", _q(TEMPERATURE_RATE, above=0.0), "fastest heating"),
            Key("max_cool_c_per_min", _q(TEMPERATURE_RATE, above=0.0), "fastest cooling"),
            Key("noise_c", _num(0.0), "sensor noise, °C", False, "0"),
        )), "chamber physics"),
        Key("table", Section("simulation-table", "simulation.table", "Table physics.", (
            Key("rate_noise_dps", _q(RATE, 0.0), "rate readback noise", False, "0"),
            Key("drive_lines", ListOf(Section(
                "simulation-table-drive-line", "simulation.table.drive_lines[]",
                "One line the powered drive puts into the gyro at rest (the vendor notes saw "
                "12.48, 24.96 and 37.44 Hz); added while the simulated interlock is closed.", (
                    Key("frequency_hz", _num(0.0), "frequency, Hz"),
                    Key("amplitude_dph", _num(0.0), "0-to-peak amplitude at the gyro's input, "
                        "deg/h"),
                )), min_items=0), "lines of the powered drive (single-axis simulated gyro)",
                False),
            Key("drive_noise_dph", _num(0.0), "extra white noise per sample while the drive is "
                "powered, deg/h (1 σ)", False, "0"),
        )), "table physics"),
        Key("inclinometer", Section("simulation-inclinometer", "simulation.inclinometer",
            "The simulated unit's inclinometer errors (instruments/sim/tilt_force.py): on a "
            "horizontal table the x channel reads scale·a_x + quadratic_per_g·a_x² + bias_g, "
            "the y channel cross_axis·a_x, each plus white noise (the z channel reads a_z).", (
                Key("scale", _num(0.5, 2.0), "x channel output per input, g/g", False, "1"),
                Key("bias_g", _num(-0.1, 0.1), "x channel zero output, g", False, "0"),
                Key("quadratic_per_g", _num(-0.1, 0.1), "x channel curvature, 1/g", False, "0"),
                Key("cross_axis", _num(-0.5, 0.5), "y channel output per g of a_x (the leak "
                    "the lateral sensitivity measures)", False, "0"),
                Key("noise_g", _num(0.0, 0.1), "white noise per sample, g (1 σ)", False, "0"),
            )), "inclinometer errors", False),
        Key("gyro_startup_s", _num(0.0, 60.0), "the simulated unit follows the supply's "
            "output (needs a supply: section): nothing while it is off, the first frame this "
            "long after the output-on, the warm-up transient restarted at each power-on; "
            "absent: the unit sends from the start, whatever the supply does", False),
        Key("turn_on_bias_dph", _num(0.0, 1e4), "with gyro_startup_s: 1 σ of a bias offset "
            "drawn afresh at each power-on (the turn-on-to-turn-on repeatability truth), deg/h",
            False, "0"),
    ))

NOTIFY = Section(
    "notify", "notify[] (a target)",
    "Who is told when something happens. Give exactly one of `url` (an apprise URL: "
    "`mailto://host:25?to=…`, `json://host:port/path`, …) or `command` (a program and its "
    "arguments, run with the event as JSON on standard input).",
    (
        Key("url", _text(), "an apprise URL", False),
        Key("command", Scalar("text_list"), "a program and its arguments", False),
        Key("on", ListOf(_choice(tuple(n.value for n in NotifyOn))), "which events",
            False, "all of them"),
    ))

STATION_ROOT = Section(
    "station", "top level",
    "A station says with what a procedure is run: the lab, its chamber, rate table and "
    "gyro interface, their addresses, identities and hard limits.",
    (
        Key("version", Scalar("integer", constant=sta.STATION_VERSION), "language version"),
        Key("name", _text(), "shown in the report"),
        Key("site", Section("site", "site", "The lab.", (
            Key("name", _text(), "laboratory name (certificate)"),
            Key("latitude_deg", _num(-90.0, 90.0), "sets the Earth-rate component removed "
                "from the bias"),
            Key("address", _text(), "postal address (certificate)", False),
            Key("height_m", _num(-500.0, 9000.0), "ellipsoidal height, m: local gravity for "
                "accelerometer calibration (WGS-84 normal gravity with its second-order height "
                "correction, NGA TR8350.2 eq. 4-1 and 4-3)", False, "0"),
            Key("gravity_mps2", _num(9.7, 9.9), "measured local gravity, m/s²; replaces the "
                "normal-gravity formula and its ±100 mGal anomaly allowance", False),
        )), "the lab"),
        Key("chamber", STATION_CHAMBER, "temperature chamber"),
        Key("table", STATION_TABLE, "rate table"),
        Key("gyro", STATION_GYRO, "gyro interface"),
        Key("supply", STATION_SUPPLY, "the unit's programmable supply", False),
        Key("coil", STATION_COIL, "Helmholtz coil on two channels of that supply", False),
        Key("simulation", SIMULATION, "simulated instruments", False),
        Key("signing_key", Scalar("path"), "the station's Ed25519 private key (`gyrocal keys`); "
            "runs are signed with it", False),
        Key("notify", ListOf(NOTIFY, min_items=0), "notification targets", False),
        Key("uncertainty", Section("uncertainty", "uncertainty", "Type B inputs of the "
            "uncertainty budget, as ± half-widths of a rectangular distribution. A key left out "
            "takes the default in metrology/uncertainty.py and the report says it was assumed.", (
                Key("table_rate_accuracy_ppm", _num(0.0), "rate accuracy of the table (its "
                    "calibration certificate), ppm", False),
                Key("chamber_temp_accuracy_c", _num(0.0), "chamber sensor plus uniformity, °C",
                    False),
                Key("latitude_accuracy_deg", _num(0.0), "site latitude, deg", False),
                Key("axis_tilt_deg", _num(0.0), "input axis to the local vertical, deg", False),
            )), "type B accuracies", False),
    ))

# -- procedure -----------------------------------------------------------------------------

_SOAK_KEYS = (
    Key("tolerance_c", _q(TEMPERATURE, above=0.0),
        "the chamber is stable when it stays within ± this of the setpoint"),
    Key("hold", _duration(), "how long it must stay within the tolerance"),
    Key("max_wait", _duration(), "give up (a fault, exit 3) if the soak has not succeeded "
        "after this long; must be at least `hold`"),
)

SOAK_DEFAULT = Section(
    "defaults-soak", "defaults.soak",
    "The soak criterion every temperature step uses unless it gives its own. All three "
    "keys are needed here.",
    _SOAK_KEYS)

SOAK_STEP = Section(
    "sequence-soak", "sequence[].soak",
    "A soak criterion for one temperature step; a key left out comes from `defaults.soak`.",
    tuple(Key(k.name, k.value, k.doc, required=False, default="defaults.soak." + k.name)
          for k in _SOAK_KEYS))

_COMMON_TEST_KEYS = (
    Key("kind", _choice(proc.TEST_KINDS), "what the test measures (selects the keys below)"),
    Key("repeats", _int(1, 100), "run the test this many times in a row", False, "1"),
    Key("label", _text(), "a name shown in the plan and the report", False),
)

_HOLD_KEYS = (
    *_COMMON_TEST_KEYS,
    Key("duration", _duration(), "how long the table stays at rest while the gyro is logged"),
    Key("settle", _duration(positive=False), "time at rest before logging starts (not logged)",
        False, "defaults.settle, else 0 s"),
)

TEST_STATIC = Section(
    "test-static", "test kind: static",
    "The table at rest: the gyro's bias at this temperature (Earth rate removed by the "
    "station latitude).", _HOLD_KEYS)

TEST_ALLAN = Section(
    "test-allan", "test kind: allan",
    "A long static hold analysed with the Allan deviation: the noise terms Q, N, B, K, R "
    "(and a Markov term when one shows). Hours, not minutes: B needs τ of ~1000 s and the "
    "record should be ten times longer.", _HOLD_KEYS)

TEST_INTERFERENCE = Section(
    "test-table_interference", "test kind: table_interference",
    "Table-induced interference (the vendor notes' turntable test): two statics of "
    "`duration`, first with the table's drive powered holding zero rate (`.powered`, a "
    "static), then with the drive off (`.off`: the interlock is opened, read back open, "
    "and closed again afterwards). The report's `table_interference` compares them: the "
    "drift (std of 1-s means) and its ratio, and the spectral lines the drive adds "
    "(frequency, 0-to-peak amplitude in both records).", _HOLD_KEYS)

TEST_MAGNETIC = Section(
    "test-magnetic", "test kind: magnetic",
    "Magnetic (Faraday) bias sensitivity (the vendor notes' coil test): three statics of "
    "`duration` at rest with the station's coil (the `coil` section) at +`field_t` "
    "(`.pos`), 0 (`.zero`, both channels off) and -`field_t` (`.neg`); the field is set, "
    "read back (journal `coil_field`) and switched off after each. The report's `magnetic` "
    "regresses the bias on the read-back field by weighted least squares: the sensitivity "
    "in deg/(h·T) with its GUM budget (each dwell's batch-means type A, the coil constant's "
    "type B) and where it falls against the notes' figures (1-10 navigation grade, ~1e4 "
    "unshielded).",
    (
        *_HOLD_KEYS,
        Key("field_t", _num(maximum=1.0, above=0.0), "|B| of the +B and -B dwells, T; within "
            "what the station's coil reaches (coil.constant_t_per_a × coil.max_current_a)"),
    ))

TEST_TILT = Section(
    "test-tilt_linearity", "test kind: tilt_linearity",
    "An inclinometer's static test (the vendor notes' tilt-sensor test; the STIM300's "
    "inclinometers, datagram 0x93 or 0xA7): the table, its axis horizontal "
    "(`table.orientation: horizontal`), in position mode as the indexing head. At each "
    "angle point (`.+15deg`, …) the table moves there at its limits, the position is read "
    "back (journal `table_position`), then `settle`, then `dwell` of logging; last a "
    "`zero_stability` hold at 0 (`.zero`); then back to 0 and rate mode. The report's "
    "`tilt_linearity`: the sensitivity and linearity (largest LS residual over the "
    "full-scale span, %) of `incl_x_g` against g·sin θ (the station's local gravity), the "
    "lateral sensitivity (the slope of `incl_y_g` against g·sin θ over the sensitivity, %) "
    "and the zero stability (std of the zero hold's 1-s means over the sensitivity, g).",
    (
        *_COMMON_TEST_KEYS,
        Key("points", _choice(tuple(proc.TILT_POINTS)), "the angle points: `vendor_90` "
            "(-90…90° in 15° steps) or `vendor_30` (-30…30° in 5° steps)"),
        Key("dwell", _duration(), "logged time at each angle point"),
        Key("zero_stability", _duration(), "logged time of the zero hold at 0°"),
        Key("settle", _duration(positive=False), "time at each angle before logging starts",
            False, "defaults.settle, else 0 s"),
    ))

SCHEDULE = Section(
    "test-sf_sweep-schedule", "sf_sweep schedule",
    "Rates generated instead of listed: `count` rates from `start_dps` to `stop_dps`, "
    "evenly (linear) or geometrically (log) spaced, rounded to what a table command carries.",
    (
        Key("spacing", _choice(proc.SPACINGS), "linear or log spacing"),
        Key("start_dps", _q(RATE, above=0.0), "the smallest rate"),
        Key("stop_dps", _q(RATE, above=0.0), "the largest rate (at least start_dps)"),
        Key("count", _int(1, proc.MAX_LIST), "how many rates"),
    ))

TEST_SWEEP = Section(
    "test-sf_sweep", "test kind: sf_sweep",
    "Scale factor: the table turns at +rate then −rate for each rate, and "
    "SF = (V₊ − V₋) / 2Ω. Give the rates either as a list (`rates_dps`) or as a "
    "`schedule`, not both.",
    (
        *_COMMON_TEST_KEYS,
        Key("rates_dps", ListOf(_q(RATE, above=0.0)),
            "rate magnitudes in order (positive; `directions` sets the signs); each at most "
            "the procedure's and the station's table limit", False),
        Key("schedule", SCHEDULE, "generated rates (instead of `rates_dps`)", False),
        Key("directions", _choice(proc.DIRECTIONS), "which signs are dwelt at", False, "both"),
        Key("dwell", _duration(), "logged time at each rate", False, "defaults.dwell"),
        Key("settle", _duration(positive=False), "time after the table reaches a rate before "
            "logging", False, "defaults.settle"),
        Key("accel_dps2", _q(ACCELERATION, above=0.0), "table acceleration between rates",
            False, "defaults.accel_dps2"),
        Key("min_revolutions", _int(1, 1000), "round each dwell up to at least this many whole "
            "table revolutions (cancels effects that repeat once a turn)", False),
    ))

TEST_THRESHOLD = Section(
    "test-threshold", "test kind: threshold",
    "Threshold and resolution (IEEE Std 952 / 1431): at each base rate the table alternates "
    "base, base + increment, base, … for every increment, smallest first. Each increment's "
    "output change (against the mean of the base dwells either side, so a linear drift "
    "cancels) is *resolved* when it exceeds the one-sided normal quantile of `confidence` "
    "times its type A uncertainty, and *within* when it lies within `max_error_fraction` of "
    "the commanded increment. The smallest increment passing both, with every larger one "
    "passing, is the threshold (base 0) or the resolution (non-zero base); its uncertainty "
    "is the increment grid's (rectangular between the largest failing increment below it "
    "and itself, U = 2u). Results: `threshold.threshold_dps`, `threshold.resolution_dps`.",
    (
        *_COMMON_TEST_KEYS,
        Key("base_rates_dps", ListOf(_q(RATE)), "signed base rates; 0 measures the threshold, "
            "a non-zero rate the resolution there; each (plus the largest increment) within "
            "the procedure's and the station's table limit"),
        Key("increments_dps", ListOf(_q(RATE, above=0.0)), "rate increments above each base, "
            "smallest first, at the table's command resolution"),
        Key("confidence", _num(above=0.5, maximum=0.999999), "one-sided confidence at which an output "
            "change counts as resolved against the noise", False,
            str(proc.DEFAULT_THRESHOLD_CONFIDENCE)),
        Key("max_error_fraction", _num(above=0.0, maximum=1.0), "how far (fraction of the "
            "commanded increment) the measured change may lie from it", False,
            str(proc.DEFAULT_THRESHOLD_ERROR_FRACTION)),
        Key("dwell", _duration(), "logged time at each base and increment dwell", False,
            "defaults.dwell"),
        Key("settle", _duration(positive=False), "time after the table reaches a rate before "
            "logging", False, "defaults.settle"),
        Key("accel_dps2", _q(ACCELERATION, above=0.0), "table acceleration between rates",
            False, "defaults.accel_dps2"),
    ))

TEST_RATE_LIMIT = Section(
    "test-rate_limit", "test kind: rate_limit",
    "Input-rate limits (IEEE Std 952 / 1431): the rates are walked up, each way, to the "
    "declared maximum (the procedure's and the station's table limits bound every one). The "
    "lowest `fit_rates` rates of each direction define a least-squares line; a rate *follows* "
    "when its output lies within `linearity_tolerance_pct` of that line. The maximum input "
    "rate each way is the largest rate that follows with every smaller one; its uncertainty "
    "is the walk's grid (rectangular up to the first rate that does not follow, U = 2u). "
    "Results: `rate_limits.max_positive_dps`, `rate_limits.max_negative_dps`.",
    (
        *_COMMON_TEST_KEYS,
        Key("rates_dps", ListOf(_q(RATE, above=0.0)), "rate magnitudes walked, smallest first"),
        Key("directions", _choice(proc.DIRECTIONS), "which ways are walked", False, "both"),
        Key("linearity_tolerance_pct", _num(above=0.0, maximum=50.0), "how far (% of the "
            "fitted output) a rate's output may lie from the line and still follow", False,
            str(proc.DEFAULT_LINEARITY_TOLERANCE_PCT)),
        Key("fit_rates", _int(1, proc.MAX_LIST), "how many of the lowest rates (each way) "
            "define the line; fewer than `rates_dps` has", False, str(proc.DEFAULT_FIT_RATES)),
        Key("dwell", _duration(), "logged time at each rate", False, "defaults.dwell"),
        Key("settle", _duration(positive=False), "time after the table reaches a rate before "
            "logging", False, "defaults.settle"),
        Key("accel_dps2", _q(ACCELERATION, above=0.0), "table acceleration between rates",
            False, "defaults.accel_dps2"),
    ))

TEST_FREQUENCY_RESPONSE = Section(
    "test-frequency_response", "test kind: frequency_response",
    "Frequency response (IEEE Std 952 / 1431): from rest, the table turns a sinusoid in "
    "synthesis mode (ACUTROL TM-8004 §4.3.4 `:Demand:Oscillator` with the peak displacement "
    "`amplitude_dps`/(2πf), then `:Mode:Synthesis`, §4.7.6; journal `table_synthesis`) at "
    "each frequency in turn; `settle_cycles` periods pass, `cycles` periods (at least "
    "`min_duration`) are logged with the sinusoid as the table rate, then the table returns "
    "to rate mode at rest. Sines fitted at the known frequency to the output and to that "
    "rate give the gain (over the nominal scale factor) and the phase, each with its type A "
    "u; the phase adds a rectangular one-sample timing term (360°·f/fs). The −3 dB "
    "bandwidth is the first crossing between the linear and logarithmic interpolations of "
    "the gains (their spread a rectangular term), U = 2u. Every frequency needs at least "
    f"{proc.MIN_SAMPLES_PER_PERIOD} samples a period, and the sinusoid's peak acceleration "
    "(2πf × amplitude) must be within the procedure's and the station's table limits. "
    "Results: `frequency_response.bandwidth_hz`, `frequency_response.phase_deg` (at "
    "`phase_at_hz`).",
    (
        *_COMMON_TEST_KEYS,
        Key("frequencies_hz", ListOf(_q(FREQUENCY, above=0.0)), "the sweep, increasing; at "
            "least two"),
        Key("amplitude_dps", _q(RATE, above=0.0), "peak rate of the sinusoid, within the "
            "table's rate limit"),
        Key("phase_at_hz", _q(FREQUENCY, above=0.0), "the frequency the phase is stated at, "
            "inside the sweep (interpolated linearly between its neighbours)"),
        Key("cycles", _int(1, 100000), "whole periods logged at each frequency", False,
            str(proc.DEFAULT_FR_CYCLES)),
        Key("settle_cycles", _int(0, 100000), "periods turned before logging (the unit's "
            "transient)", False, str(proc.DEFAULT_FR_SETTLE_CYCLES)),
        Key("min_duration", _duration(), "the least logged time at a frequency", False, "1 s"),
    ))

TEST_TURN_ON = Section(
    "test-turn_on", "test kind: turn_on",
    "Turn-on time and warm-up (IEEE Std 952 / 1431): the table at rest, the station's supply "
    "switches the unit off (read back off), `off` passes, the output is switched on; the "
    "gyro is polled from that command until its first valid frame (journal "
    "`unit_power_cycle`; a unit silent for 30 s is a fault), then logged for `duration`. "
    "The turn-on time is the middle of the poll interval the first frame came in "
    "(rectangular u); b∞ + A·e^(−t/τ) is fitted to 1-s means of the bias from the "
    "output-on (type A u); the time until the bias stays within ±`band_dph` of b∞ follows "
    "from the fit (u propagated), the measured one beside it; U = 2u. Needs a station with "
    "a `supply:` section. Results: `turn_on.time_to_first_data_s`, `turn_on.warmup_tau_s`, "
    "`turn_on.warmup_amplitude_dph`, `turn_on.time_to_band_s`.",
    (
        *_COMMON_TEST_KEYS,
        Key("off", _duration(), "time the unit is off before the output-on (cool-down)"),
        Key("duration", _duration(), "logged time from the first frame; several warm-up "
            "time constants"),
        Key("band_dph", _num(above=0.0, maximum=1e6), "the stated band about the settled "
            "bias, deg/h"),
    ))

TEST_TURN_ON_REPEATABILITY = Section(
    "test-turn_on_repeatability", "test kind: turn_on_repeatability",
    "Turn-on-to-turn-on bias repeatability (IEEE Std 952 / 1431): `cycles` power cycles "
    "(plan steps `….c1`, `….c2`, …), each: the table at rest, the supply off for `off` (the "
    "cool-down, read back off), on, the first valid frame awaited (journal "
    "`unit_power_cycle`), `settle` passes, `duration` is logged. The bias of a cycle is its "
    "record's mean; the repeatability is their standard deviation with u = s/√(2(N−1)), "
    "U = 2u; the in-run bias stability (pooled standard deviation of 1-s means within the "
    "cycles) is given beside it. Needs a station with a `supply:` section. Result: "
    "`turn_on_repeatability.std_dph`.",
    (
        *_COMMON_TEST_KEYS,
        Key("cycles", _int(2, 100), "how many power cycles (N)"),
        Key("off", _duration(), "time the unit is off before each power-on (cool-down)"),
        Key("settle", _duration(positive=False), "time after the first frame before logging "
            "(the stated settling time)"),
        Key("duration", _duration(), "logged time of each cycle"),
    ))

TEMPERATURE_STEP = Section(
    "sequence", "sequence[] (a temperature step)",
    "One chamber setpoint: ramp to it, soak until stable, then run its tests in order.",
    (
        Key("setpoint_c", _q(TEMPERATURE, -273.15), "chamber setpoint, within the procedure's "
            "and the station's chamber limits"),
        Key("ramp_c_per_min", _q(TEMPERATURE_RATE, above=0.0), "how fast the setpoint is walked "
            f"(at least {proc.MIN_RAMP_C_PER_MIN} °C/min)", False, "defaults.ramp_c_per_min"),
        Key("soak", SOAK_STEP, "when the chamber counts as stable", False, "defaults.soak"),
        Key("label", _text(), "a name shown in the plan and the report", False),
        Key("tests", ListOf(Variants("kind", (("static", TEST_STATIC), ("sf_sweep", TEST_SWEEP),
                                              ("allan", TEST_ALLAN),
                                              ("table_interference", TEST_INTERFERENCE),
                                              ("threshold", TEST_THRESHOLD),
                                              ("rate_limit", TEST_RATE_LIMIT),
                                              ("frequency_response", TEST_FREQUENCY_RESPONSE),
                                              ("magnetic", TEST_MAGNETIC),
                                              ("tilt_linearity", TEST_TILT),
                                              ("turn_on", TEST_TURN_ON),
                                              ("turn_on_repeatability",
                                               TEST_TURN_ON_REPEATABILITY))),
                            min_items=0),
            "what is measured at this temperature, in order (an empty list just soaks)", False),
    ))

ACCEPTANCE = Section(
    "acceptance", "acceptance[] (a limit)",
    "One pass/fail limit on a number of `report/results.json`. Give exactly one of `max` "
    "or `min`. The metric must be one the sequence measures (a sweep for nonlinearity, "
    "sweeps at two temperatures for the temperature sensitivity, …); the list of metrics "
    "is in [the results reference](run-folder.md#metrics).",
    (
        Key("name", _text(), "how the limit is shown in the report (unique)"),
        Key("metric", _choice(tuple(METRICS)), "the results.json key path judged"),
        Key("max", _num(), "the largest value that passes", False),
        Key("min", _num(), "the smallest value that passes", False),
        Key("unit", _text(), "the limit's unit, checked against the metric's own unit "
            "(spelling-insensitive: `°/√h` = `deg/sqrt(h)`); the report and the certificate "
            "print it beside the value and the limit", False,
            "the metric's unit (the gyro's output units for `scale_factor_ls.*`)"),
        Key("decision_rule", _choice(("simple", "guarded")), "`simple`: the value against the "
            "limit; `guarded`: value ± U must lie inside the limit to PASS (ILAC-G8), outside "
            "it to FAIL, otherwise CONDITIONAL", False, "simple"),
    ))

MOUNTING = Section(
    "mountings", "mountings[] (a fixture face)",
    "For a three-axis IMU in a hexahedron fixture: which IMU axis points up the table axis. "
    "Every axis (x, y, z) must be up once. The plan gets a `remount` step per mounting, "
    "where the run waits for `gyrocal confirm RUN_DIR`.",
    (
        Key("name", _text(), "letters, digits, - and _ (part of every step id, e.g. `MY`)"),
        Key("up", _text(), "the IMU axis with its sign: `+x`, `-y`, `z`"),
        Key("face", _text(), "the fixture face the operator is told to use", False),
    ))

_DEFAULTS = Section(
    "defaults", "defaults",
    "What temperature steps and tests inherit when they leave a key out. A key needed by a "
    "step or test that is neither given there nor here is an error naming both places.",
    (
        Key("ramp_c_per_min", _q(TEMPERATURE_RATE, above=0.0), "chamber ramp rate", False),
        Key("soak", SOAK_DEFAULT, "soak criterion", False),
        Key("dwell", _duration(), "logged time at each rate of a sweep", False),
        Key("settle", _duration(positive=False), "time before logging starts", False),
        Key("accel_dps2", _q(ACCELERATION, above=0.0), "table acceleration", False),
        Key("sample_rate_hz", _q(FREQUENCY, above=0.0), "logging rate; at most the gyro's "
            "output rate (station `gyro.sample_rate_hz`)", False, "the station's gyro rate"),
    ))

PROCEDURE_ROOT = Section(
    "procedure", "top level",
    "A procedure says what to measure: at which temperatures, which rates, for how long, and "
    "what passes. It names a station (with what) and may run on any station whose limits "
    "contain its own.",
    (
        Key("version", Scalar("integer", constant=proc.PROCEDURE_VERSION), "language version"),
        Key("name", _text(), "shown in the plan, the report and the certificate"),
        Key("description", _text(), "free text", False),
        Key("unit_under_test", Section(
            "unit_under_test", "unit_under_test", "The gyro being calibrated. A unit is "
            "identified by model and serial together (the runs database and `history` use both).",
            (
                Key("model", _text(), "the gyro's model"),
                Key("serial", Scalar("serial"), "its serial number (digits are read as text)"),
                Key("output_units", _choice(proc.OUTPUT_UNITS), "what the gyro outputs"),
                Key("nominal_scale_factor", _num(above=0.0), "output units per deg/s, from "
                    "the data sheet; a measured SF far from it makes the run INVALID"),
            )), "the gyro being calibrated"),
        Key("station", Either((Scalar("path"), STATION_ROOT)), "the station file, relative to this procedure (or a station mapping written "
            "inline); `--station` on the command line overrides it"),
        Key("safety", Section(
            "safety", "safety", "The procedure's own hard limits; they must lie inside the "
            "station's, and every setpoint, ramp, rate and acceleration is checked against both.",
            (
                Key("chamber", Section("safety-chamber", "safety.chamber", "Chamber limits.", (
                    Key("min_temp_c", _q(TEMPERATURE, -273.15), "lowest setpoint"),
                    Key("max_temp_c", _q(TEMPERATURE, -273.15), "highest setpoint"),
                    Key("max_ramp_c_per_min", _q(TEMPERATURE_RATE, above=0.0), "fastest ramp"),
                )), "chamber limits"),
                Key("table", Section("safety-table", "safety.table", "Rate-table limits.", (
                    Key("max_rate_dps", _q(RATE, above=0.0), "largest rate magnitude"),
                    Key("max_accel_dps2", _q(ACCELERATION, above=0.0), "largest acceleration"),
                )), "rate-table limits"),
            )), "hard limits"),
        Key("defaults", _DEFAULTS, "values inherited by steps and tests", False),
        Key("data_quality", Section(
            "data_quality", "data_quality", "When a logged step is good enough to keep.", (
                Key("max_lost_frame_fraction", _num(0.0, 0.5), "lost + CRC-failed frames per "
                    "logged step above which the step is repeated"),
                Key("max_step_repeats", _int(0, 20), "how often a bad step is repeated before "
                    "the run faults"),
                Key("sf_tolerance_pct", _num(above=0.0, maximum=100.0), "how far (%) the "
                    "measured SF may lie from `nominal_scale_factor` before the run is INVALID",
                    False, "5"),
            )), "data-quality thresholds"),
        Key("sequence", ListOf(TEMPERATURE_STEP), "the temperature steps, in order"),
        Key("acceptance", ListOf(ACCEPTANCE, min_items=0), "pass/fail limits", False),
        Key("mountings", ListOf(MOUNTING), "fixture faces of a three-axis IMU calibration",
            False),
        Key("mounting_order", _choice(proc.MOUNTING_ORDERS), "`temperatures_inside`: every "
            "temperature in one mounting, then remount; `mountings_inside`: every mounting at "
            "each temperature (only with `mountings`)", False, "temperatures_inside"),
        Key("max_duration", _duration(), "the longest the plan may take (at most 90 days)",
            False, "14 d"),
        Key("templates", Scalar("anything"), "free-form: a home for YAML anchors "
            "(`&sweep`) reused elsewhere with `*sweep` or `<<: *sweep`", False),
    ))

# -- gyro model ------------------------------------------------------------------------------

NOISE = Section(
    "noise", "noise",
    "IEEE Std 952 noise coefficients of the rate noise; a key left out is 0. Allan variance: "
    "σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²τ/3 + R²τ²/2.",
    tuple(Key(t.model_key, _num(0.0), f"{t.symbol}, {t.name}, {t.unit}", False, "0")
          for t in NOISE_TERMS))


def _effect_section(name: str) -> Section:
    effect = EFFECTS[name]
    keys = [Key("name", Scalar("choice", choices=(name,)), "the effect's catalogue name")]
    for param in effect.params:
        minimum = None if param.minimum == float("-inf") else param.minimum
        value = _num(above=minimum) if param.minimum_exclusive else _num(minimum)
        keys.append(Key(param.key, value, f"{param.description} ({param.unit})"))
    return Section(f"effect-{name}", f"effect: {name}",
                   f"{effect.cause}. `{effect.equation}`.", tuple(keys))


EFFECT_VARIANTS = Variants("name", tuple((name, _effect_section(name)) for name in EFFECTS))

_MODEL_NUMBERS = (
    Key("reference_temp_c", _num(), "T0, the temperature the coefficients refer to", False, "0"),
    Key("bias_dph", _num(), "bias at T0, deg/h", False, "0"),
    Key("bias_tempco_dph_per_c", _num(), "bias change per °C from T0, deg/h/°C", False, "0"),
    Key("sf_error_ppm", _num(), "scale-factor error at T0, ppm", False, "0"),
    Key("sf_tempco_ppm_per_c", _num(), "scale-factor change per °C, ppm/°C", False, "0"),
)

MODEL_V1 = Section(
    "model-v1", "version 1 (one axis)",
    "A single-axis gyro: output = scale_factor · ω_ind with "
    "ω_ind = (1 + 1e-6·s(T))·ω_t + NL(ω_t) + [b(T) + bias effects + w(t)] / 3600, "
    "s(T) = sf_error_ppm + sf_tempco_ppm_per_c·ΔT, "
    "b(T) = bias_dph + bias_tempco_dph_per_c·ΔT + earth_rate_dph, ΔT = T − reference_temp_c. "
    "Every key but `version` and `scale_factor` may be left out (0, or no effect).",
    (
        Key("version", Scalar("integer", constant=1), "1"),
        Key("name", _text(), "free text", False),
        Key("output_units", _choice(MODEL_OUTPUT_UNITS), "informational", False, "deg/s"),
        Key("scale_factor", _num(), "output units per deg/s (non-zero)"),
        *_MODEL_NUMBERS,
        Key("earth_rate_dph", _num(), "Earth-rate component along the input axis, deg/h "
            "(15.041067·sin(latitude) for an axis pointing up)", False, "0"),
        Key("noise", NOISE, "noise coefficients", False),
        Key("effects", ListOf(EFFECT_VARIANTS, min_items=0), "catalogue effects, each at "
            "most once", False),
    ))

MODEL_AXIS = Section(
    "model-v2-axis", "axes.x / axes.y / axes.z",
    "One axis of a version-2 model: the keys of a version-1 model without `version` and "
    "without `earth_rate_dph` (an IMU's Earth rate is a vector set by the mounting and the "
    "latitude). `output_units` and `reference_temp_c` default to the file's.",
    tuple(k for k in MODEL_V1.keys if k.name not in ("version", "earth_rate_dph")))

_MATRIX_PAIRS = tuple(f"{a}{b}" for a in AXES for b in AXES if a != b)

MODEL_V2 = Section(
    "model-v2", "version 2 (three-axis IMU)",
    "Three single-axis models coupled by input-referred misalignment: axis i senses "
    "E_ij (µrad) of the rate about axis j, E_ij(T) = misalignment_urad + "
    "misalignment_tempco_urad_per_c·ΔT.",
    (
        Key("version", Scalar("integer", constant=2), "2"),
        Key("name", _text(), "free text", False),
        Key("output_units", _choice(MODEL_OUTPUT_UNITS), "informational", False, "deg/s"),
        Key("reference_temp_c", _num(), "T0 of every axis", False, "0"),
        Key("axes", Section("model-v2-axes", "axes", "The three axes, all required.", tuple(
            Key(a, MODEL_AXIS, f"axis {a}") for a in AXES)), "the three axes"),
        Key("misalignment_urad", Section("model-v2-misalignment", "misalignment_urad",
            "Off-diagonal elements by row then column axis: " + ", ".join(_MATRIX_PAIRS)
            + "; an element left out is 0.",
            tuple(Key(p, _num(), f"E_{p}", False, "0") for p in _MATRIX_PAIRS)),
            "E_ij at T0, µrad", False),
        Key("misalignment_tempco_urad_per_c", Section(
            "model-v2-misalignment-tempco", "misalignment_tempco_urad_per_c",
            "Temperature coefficients of the same elements; an element left out is 0.", tuple(Key(p, _num(), f"E_{p} per °C", False, "0") for p in _MATRIX_PAIRS)),
            "E_ij change per °C, µrad/°C", False),
        Key("accelerometers", Section(
            "model-v2-accelerometers", "accelerometers",
            "The accelerometer triad, in g (9.80665 m/s²): output_i = (1 + k_i(T))·f_in,i + "
            "b_i(T) + noise, f_in,i = f_i + Σ M_ij(T)·f_j, k_i(T) = 1e-6·(sf_error_ppm + "
            "sf_tempco_ppm_per_c·ΔT), b_i(T) = 1e-3·(bias_mg + bias_tempco_mg_per_c·ΔT); "
            "white noise of the given velocity random walk. Left out: ideal accelerometers.",
            (
                Key("axes", Section("model-v2-acc-axes", "accelerometers.axes",
                    "The three accelerometers, all required.", tuple(
                        Key(a, Section(f"model-v2-acc-axis-{a}", f"accelerometers.axes.{a}",
                            f"Accelerometer {a}; a key left out is 0.", (
                                Key("bias_mg", _num(), "bias at T0, mg", False, "0"),
                                Key("bias_tempco_mg_per_c", _num(), "bias change per °C, mg/°C",
                                    False, "0"),
                                Key("sf_error_ppm", _num(), "scale-factor error at T0, ppm",
                                    False, "0"),
                                Key("sf_tempco_ppm_per_c", _num(), "scale-factor change per "
                                    "°C, ppm/°C", False, "0"),
                                Key("vrw_mps_per_rth", _num(0.0), "velocity random walk, "
                                    "m/s/√h", False, "0"),
                            )), f"accelerometer {a}") for a in AXES)),
                    "the three accelerometers"),
                Key("misalignment_urad", Section(
                    "model-v2-acc-misalignment", "accelerometers.misalignment_urad",
                    "M_ij: accelerometer i senses M_ij of the specific force along j; an element "
                    "left out is 0.", tuple(Key(p, _num(), f"M_{p}", False, "0")
                                            for p in _MATRIX_PAIRS)), "M_ij at T0, µrad", False),
                Key("misalignment_tempco_urad_per_c", Section(
                    "model-v2-acc-misalignment-tempco",
                    "accelerometers.misalignment_tempco_urad_per_c",
                    "Temperature coefficients of the same elements; an element left out is 0.",
                    tuple(Key(p, _num(), f"M_{p} per °C", False, "0") for p in _MATRIX_PAIRS)),
                    "M_ij change per °C, µrad/°C", False),
            )), "accelerometer triad (seeds/003 §3.2)", False),
    ))

PROCEDURE = Language(
    "procedure", "Procedure file", "", PROCEDURE_ROOT,
    "docs/reference/procedure.md", "docs/schemas/procedure.schema.json",
    ("procedures/smoke.yaml",))
STATION = Language(
    "station", "Station file", "", STATION_ROOT,
    "docs/reference/station.md", "docs/schemas/station.schema.json", ("stations/sim.yaml",))
MODEL = Language(
    "model", "Gyro model file", "", Either((MODEL_V1, MODEL_V2)),
    "docs/reference/model.md", "docs/schemas/model.schema.json", ("gyro-models/nominal-fog.yaml",))
LANGUAGES = (PROCEDURE, STATION, MODEL)

#: what each acceptance metric needs from the sequence, in words (for the results reference)
METRIC_NEEDS = {key: metric.needs.text for key, metric in METRICS.items()}


def section_at(root: Shape, path: tuple[str | int, ...], data: object = None
               ) -> tuple[Section | None, Key | None]:
    """The section a key path lies in and the key itself (None where the path leaves the
    description): how a validation error finds the part of the reference that explains it.
    ``data`` (the loaded document) picks the variant: a test's ``kind``, a model's version."""
    shape: Shape = root
    section: Section | None = None
    key: Key | None = None
    for part in path:
        shape = choose(shape, data)
        if isinstance(shape, ListOf) and isinstance(part, int):
            shape = shape.item
        elif isinstance(shape, Section) and isinstance(part, str):
            section, key = shape, shape.key(part)
            if key is None:
                return section, None
            shape = key.value
        else:
            return section, key
        data = _child(data, part)
    return section, key


def _child(data: object, part: str | int) -> object:
    if isinstance(data, dict) and isinstance(part, str):
        return data.get(part)
    if isinstance(data, list) and isinstance(part, int) and 0 <= part < len(data):
        return data[part]
    return None


def choose(shape: Shape, data: object) -> Shape:
    """A Variants or Either resolved by the data it describes (its first option if none fits)."""
    if isinstance(shape, Variants):
        wanted = data.get(shape.discriminator) if isinstance(data, dict) else None
        return next((s for name, s in shape.sections if name == wanted), shape.sections[0][1])
    if isinstance(shape, Either):
        for option in shape.options:
            if isinstance(option, Section) and isinstance(data, dict):
                version = option.key("version")
                constant = version.value.constant if version and isinstance(
                    version.value, Scalar) else None
                if constant is None or data.get("version") == constant:
                    return option
            if isinstance(option, Scalar) and not isinstance(data, dict):
                return option
        return shape.options[0]
    return shape
