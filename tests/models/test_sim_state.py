"""A simulator's state through JSON and back: what follows is what would have followed.

A resumed dry run restores the state a killed session journaled
(``models/sim_state.py``); these check each piece in isolation: after a
restore into a simulator that meanwhile did something else, its output is
the output the original would have given, bit for bit. And a snapshot is
data: it cannot name a class outside gyrocal nor fit a different simulator.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrocal.models.chamber import ChamberPhysics
from gyrocal.models.clock import SimClock
from gyrocal.models.gyro_model import EffectSpec, NoiseParams, load_model
from gyrocal.models.gyro_sim import GyroSimulator
from gyrocal.models.sim_state import SimStateError, capture, decode, restore
from gyrocal.models.table import TablePhysics

MODELS = Path(__file__).resolve().parents[2] / "gyro-models"
FS_HZ = 200.0


def through_json(state: dict) -> dict:
    """As the journal writes and reads it (no NaN, keys sorted)."""
    return json.loads(json.dumps(state, sort_keys=True, allow_nan=False))


def every_state_model():
    """Every noise term (flicker bank, walk, ramp, Markov), pulse quantization and the
    effects that carry history (thermal lag, hysteresis, rate bandwidth)."""
    model = load_model(MODELS / "nominal-fog.yaml")
    for name, params in [("temp_hysteresis", {"dph": 0.2}),
                         ("markov_bias", {"sigma_dph": 0.1, "tau_s": 20.0}),
                         ("quantization", {"pulse_arcsec": 0.5}),
                         ("rate_bandwidth", {"bandwidth_hz": 20.0})]:
        model = model.with_effect(EffectSpec(name, params))
    return replace(model, noise=NoiseParams(0.5, 0.01, 0.03, 0.02, 0.5))


def inputs(n: int, start: int):
    t_s = (start + np.arange(n)) / FS_HZ
    return 10.0 * np.sin(t_s / 3.0), 23.0 + 0.01 * t_s


def test_a_gyro_simulator_restored_continues_bit_for_bit() -> None:
    model = every_state_model()
    original = GyroSimulator(model, FS_HZ, seed=3)
    original.generate(*inputs(5000, 0))
    snapshot = through_json(capture(original))
    expected = original.generate(*inputs(3000, 5000)).gyro

    other = GyroSimulator(model, FS_HZ, seed=99)          # another history altogether
    other.generate(*inputs(1234, 0))
    restore(other, snapshot)
    assert other.generate(*inputs(3000, 5000)).gyro.tobytes() == expected.tobytes()


def test_chamber_and_table_restored_on_a_fresh_clock_continue_bit_for_bit() -> None:
    clock = SimClock()
    chamber = ChamberPhysics(clock, tau_s=120.0, noise_c=0.05, seed=1)
    table = TablePhysics(clock, rate_noise_dps=0.001, seed=2)
    table.close_interlock()
    table.set_mode_rate()
    for minute in range(30):          # a software ramp: a segment every 10 s
        chamber.set_setpoint(22.0 + minute * 0.5)
        table.set_rate_demand_dps(float(minute % 7))
        clock.sleep(10.0)
        chamber.temperature_c()
        table.read_rate_dps()
    state = {"clock_s": clock.now_s(), "chamber": through_json(capture(chamber)),
             "table": through_json(capture(table))}
    assert len(state["chamber"]["custom"]["segments"]["list"]) <= 8   # recent history only
    times_s = clock.now_s() + np.linspace(-5.0, 200.0, 50)
    expected = (chamber.air_temperature_c(times_s), table.rate_dps(times_s),
                table.angle_deg(times_s), [chamber.temperature_c() for _ in range(5)],
                [table.read_rate_dps() for _ in range(5)])

    fresh = SimClock()
    chamber2 = ChamberPhysics(fresh, tau_s=120.0, noise_c=0.05, seed=7)
    table2 = TablePhysics(fresh, rate_noise_dps=0.001, seed=8)
    fresh.sleep(3.0)
    fresh.restore_s(state["clock_s"])
    restore(chamber2, state["chamber"])
    restore(table2, state["table"])
    got = (chamber2.air_temperature_c(times_s), table2.rate_dps(times_s),
           table2.angle_deg(times_s), [chamber2.temperature_c() for _ in range(5)],
           [table2.read_rate_dps() for _ in range(5)])
    for a, b in zip(expected, got, strict=True):
        assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
    assert (table2.mode, table2.interlock_closed) == (table.mode, table.interlock_closed)


def test_a_snapshot_is_data_it_names_only_gyrocal_dataclasses_and_fits_one_class() -> None:
    with pytest.raises(SimStateError, match="not one of gyrocal's dataclasses"):
        decode({"dataclass": "subprocess:Popen", "fields": {"args": "true"}})
    with pytest.raises(SimStateError, match="not one of gyrocal's dataclasses"):
        decode({"dataclass": "gyrocal.models.sim_state:capture", "fields": {}})
    table = TablePhysics(SimClock())
    chamber = ChamberPhysics(SimClock())
    with pytest.raises(SimStateError, match="cannot restore"):
        restore(table, capture(chamber))
    simulator = GyroSimulator(load_model(MODELS / "nominal-fog.yaml"), FS_HZ, seed=1)
    state = capture(simulator)
    del state["attrs"]["_index"]
    with pytest.raises(SimStateError, match="expected"):
        restore(simulator, state)


def _nested_generator_form(value):
    """A snapshot as the first version wrote it: every generator's state as nested objects,
    its 128-bit words as ``{"hex": ...}`` (journals of runs made before the text form)."""
    if isinstance(value, dict):
        if set(value) == {"pcg64"}:
            state, inc, has_uint32, uinteger = value["pcg64"].split("/")
            return {"rng": {"bit_generator": "PCG64", "has_uint32": int(has_uint32),
                            "state": {"inc": {"hex": hex(int(inc, 16))},
                                      "state": {"hex": hex(int(state, 16))}},
                            "uinteger": int(uinteger)}}
        return {key: _nested_generator_form(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_nested_generator_form(item) for item in value]
    return value


def test_generators_are_one_text_each_and_old_nested_snapshots_still_restore() -> None:
    model = every_state_model()
    original = GyroSimulator(model, FS_HZ, seed=5)
    original.generate(*inputs(4000, 0))
    snapshot = through_json(capture(original))
    expected = original.generate(*inputs(2500, 4000)).gyro
    text = json.dumps(snapshot)
    assert '"pcg64"' in text and '"rng"' not in text and '"hex"' not in text
    old = _nested_generator_form(snapshot)
    assert '"pcg64"' not in json.dumps(old)
    for state in (snapshot, old):
        other = GyroSimulator(model, FS_HZ, seed=42)
        other.generate(*inputs(777, 0))
        restore(other, through_json(state))
        assert other.generate(*inputs(2500, 4000)).gyro.tobytes() == expected.tobytes()


def test_a_generator_state_that_is_not_pcg64_text_is_refused_by_name() -> None:
    for text in ("1f/2b/0", "zz/1/0/0", 17):
        with pytest.raises(SimStateError, match="not a PCG64 state"):
            decode({"pcg64": text}, np.random.default_rng(1))
