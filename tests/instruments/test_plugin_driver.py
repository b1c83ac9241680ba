"""A chamber driver from an external distribution, found through the ``gyrocal.drivers`` entry point.

tests/plugins/gyrocal_plugin_demo/ is a distribution as pip leaves it on disk
(a module beside its ``*.dist-info`` with ``entry_points.txt``). Put on the
path of a fresh ``gyrocal`` process, importlib.metadata discovers it for real;
nothing inside gyrocal names it. The run then drives the plug-in's driver
against the plug-in's simulator (a TCP server on loopback).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

from gyrocal.instruments.driver_spec import Role
from gyrocal.instruments.registry import ENTRY_POINT_GROUP, build_registry, registry

ROOT = Path(__file__).resolve().parents[2]
PLUGIN = ROOT / "tests" / "plugins" / "gyrocal_plugin_demo"
GYROCAL = [sys.executable, "-m", "gyrocal"]


def _project(tmp_path: Path, **chamber_extra) -> Path:
    """A copy of the smoke procedure on the simulated station with the chamber swapped for the plug-in's."""
    (tmp_path / "stations").mkdir()
    (tmp_path / "procedures").mkdir()
    station = yaml.safe_load((ROOT / "stations" / "sim.yaml").read_text())
    station["chamber"] = {
        "driver": "demo_chamber", "address": "sim", "zone": 1,
        "identity": {"make": "Demo Chambers", "model": "TC-1", "serial": "DEMO-0001"},
        "limits": {"min_temp_c": -40.0, "max_temp_c": 120.0, "max_ramp_c_per_min": 5.0},
        "safe_state": {"action": "setpoint", "setpoint_c": 25.0}, **chamber_extra}
    (tmp_path / "gyro-models").mkdir()
    shutil.copy(ROOT / "gyro-models" / "nominal-fog.yaml", tmp_path / "gyro-models")
    (tmp_path / "stations" / "demo.yaml").write_text(yaml.safe_dump(station, sort_keys=False))
    procedure = (ROOT / "procedures" / "smoke.yaml").read_text()
    path = tmp_path / "procedures" / "smoke.yaml"
    path.write_text(procedure.replace("../stations/sim.yaml", "../stations/demo.yaml"))
    return path


def _gyrocal(*args: str, plugin: bool = True, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if plugin:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(PLUGIN), env.get("PYTHONPATH")]))
    return subprocess.run([*GYROCAL, *args], capture_output=True, text=True, env=env, cwd=cwd,
                          timeout=300)


def test_the_installed_registry_holds_the_builtin_drivers_and_no_demo():
    assert registry().names(Role.CHAMBER) == ("watlow_f4", "watlow_f4t")
    assert registry().names(Role.TABLE) == ("acutrol3000",)
    assert registry().names(Role.GYRO) == ("stim300", "keysight_34465a", "keysight_53230a")
    assert registry().names(Role.SUPPLY) == ("keysight_e36300",)


def test_importlib_metadata_finds_the_demo_distribution_on_the_path():
    code = ("import json; from importlib import metadata; "
            f"eps = metadata.entry_points(group={ENTRY_POINT_GROUP!r}); "
            "print(json.dumps([[e.name, e.value, e.dist.name] for e in eps]))")
    env = {**os.environ, "PYTHONPATH": str(PLUGIN)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout
    assert json.loads(out) == [["demo_chamber", "gyrocal_plugin_demo:SPEC", "gyrocal-plugin-demo"]]


def test_a_broken_plugin_is_left_out_and_named(tmp_path):
    from importlib.metadata import EntryPoint

    broken = EntryPoint("bad", "no_such_module_xyz:SPEC", ENTRY_POINT_GROUP)
    built = build_registry([broken])
    assert built.names(Role.CHAMBER) == ("watlow_f4", "watlow_f4t")
    assert len(built.problems) == 1 and "no_such_module_xyz:SPEC" in built.problems[0]
    assert "ModuleNotFoundError" in built.problems[0]


def test_without_the_plugin_the_station_is_refused_naming_file_line_and_known_drivers(tmp_path):
    proc = _gyrocal("validate", str(_project(tmp_path)), plugin=False, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    text = proc.stdout + proc.stderr
    assert "demo.yaml:" in text and "chamber.driver: no chamber driver 'demo_chamber'" in text
    assert "known: watlow_f4, watlow_f4t" in text
    assert "Traceback" not in text


def test_the_plugins_own_setting_is_checked_against_its_schema(tmp_path):
    proc = _gyrocal("validate", str(_project(tmp_path, zone=9)), cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "chamber.zone: 9 is above the maximum 4" in proc.stdout + proc.stderr


def test_validate_and_a_dry_run_use_the_plugin_chamber_end_to_end(tmp_path):
    procedure = _project(tmp_path)
    proc = _gyrocal("validate", str(procedure), cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr

    run = tmp_path / "run"
    proc = _gyrocal("run", str(procedure), "--sim", "--out", str(run), cwd=tmp_path)
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr   # 1: acceptance, still a full run
    manifest = json.loads((run / "manifest.json").read_text())
    chamber = manifest["instruments"]["chamber"]
    assert chamber["driver"] == "demo_chamber"
    assert chamber["description"] == "Demo Chambers,TC-1,DEMO-0001"   # the simulator's ID? reply


def test_a_fault_injected_in_the_plugin_simulator_is_a_fault_exit_3(tmp_path):
    procedure = _project(tmp_path)
    run = tmp_path / "run"
    proc = _gyrocal("run", str(procedure), "--sim", "--out", str(run),
                    "--inject", "chamber.alarm:always@T01.soak", cwd=tmp_path)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 3, text
    assert "alarm" in text and "Traceback" not in text
    journal = (run / "journal.jsonl").read_text()
    assert '"event":"fault_injected"' in journal and '"instrument":"chamber"' in journal
