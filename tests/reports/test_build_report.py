"""build_report on a real simulated run: results.json keys, numbers against the simulated truth.

The smoke station's gyro is gyro-models/nominal-fog.yaml: SF = 1 + 1e-6·(50 + 20·(T_s − 25)),
bias 2 + 0.03·(T_s − 25) deg/h plus the model's Earth rate 11.6 deg/h, and the analysis removes
the Earth rate of the station latitude (read from stations/sim.yaml). T_s is the sensor temperature
(thermal lag 600 s), measured in the log, so the truth is evaluated there.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from gyrocal.cli import main
from gyrocal.metrology.decision import Decision
from gyrocal.metrology.metrics import METRICS, metric_number
from gyrocal.record.journal import read_journal
from gyrocal.reports.acceptance import evaluate_acceptance
from gyrocal.reports.results import REQUIRED_KEYS

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="session")
def results(smoke_run) -> dict:
    return json.loads((smoke_run / "report" / "results.json").read_text())


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def test_every_spec_key_with_its_type(results):
    for key in REQUIRED_KEYS:
        assert key in results, key
    assert set(results["unit_under_test"]) >= {"model", "serial"}
    assert results["unit_under_test"]["serial"] == "SIM-0001"
    assert len(results["scale_factor"]) == 2
    for entry in results["scale_factor"]:
        assert all(_is_number(entry[k]) for k in ("temp_c", "sf", "sf_plus", "sf_minus"))
    assert all(_is_number(results["scale_factor_ls"][k]) for k in ("sf", "bias"))
    assert all(_is_number(results["nonlinearity"][k]) for k in ("rms_pct", "max_ppm_fs"))
    assert _is_number(results["asymmetry_ppm"])
    assert all(_is_number(results["sf_temperature"][k])
               for k in ("instability_pct", "sensitivity_ppm_per_c"))
    assert [b["temp_c"] for b in results["bias"]] == [23.0, 27.0]
    assert _is_number(results["bias_temperature"]["sensitivity_dph_per_c"])
    allan = results["allan"]
    assert len(allan["tau_s"]) == len(allan["adev_dph"]) > 10
    assert set(allan["fit"]) == {"Q_arcsec", "N_deg_per_rth", "B_dph", "K_dph_per_rth",
                                 "R_dph_per_h", "markov"}
    comp = results["compensation"]
    assert [p[0] for p in comp["bias_dph_vs_temp"]] == [23.0, 27.0]
    assert [p[0] for p in comp["sf_vs_temp"]] == [23.0, 27.0]
    for item in results["acceptance"]:
        assert set(item) >= {"name", "value", "limit", "pass"}


def _truth_sf(sensor_c: float) -> float:
    return 1.0 + 1e-6 * (50.0 + 20.0 * (sensor_c - 25.0))


def test_scale_factor_matches_the_simulated_truth(results):
    for entry in results["scale_factor"]:
        truth = _truth_sf(entry["sensor_temp_c"])
        # ± dwells of 10 s at 2 kHz with N = 0.01 deg/√h: a few ppm of noise; the tempco
        # alone moves SF by 50–70 ppm here, so 10 ppm separates right from wrong.
        assert entry["sf"] == pytest.approx(truth, abs=10e-6)
        assert entry["sf_plus"] == pytest.approx(truth, abs=15e-6)
        assert entry["sf_minus"] == pytest.approx(truth, abs=15e-6)
    # the model has no nonlinearity: residuals are noise (a few ppm of full scale)
    assert results["nonlinearity"]["max_ppm_fs"] < 20.0
    ref = results["scale_factor_ls"]
    # 23 and 27 °C are both 2 °C from the 25 °C reference: the tie goes to the lower one
    assert ref["temp_c"] == 23.0
    assert ref["sf"] == results["scale_factor"][0]["sf"]


def test_bias_has_the_station_earth_rate_removed(results):
    from gyrocal.orchestrator.station import load_station

    latitude = load_station(ROOT / "stations" / "sim.yaml").site.latitude_deg
    earth_removed = 15.041067 * math.sin(math.radians(latitude))
    assert results["earth_rate_removed_dph"] == pytest.approx(earth_removed, rel=1e-9)
    for point in results["bias"]:
        sensor = point["sensor_temp_c"]
        truth = 2.0 + 0.03 * (sensor - 25.0) + 11.6 - earth_removed
        # 30 s hold: ARW 0.01 deg/√h → 0.11 deg/h (1σ) plus B 0.03 deg/h.
        assert point["bias_dph"] == pytest.approx(truth, abs=0.45)
        assert point["source"] == "static"


def test_every_calibrated_quantity_carries_its_gum_uncertainty(results):
    """u, U, k and a budget beside each value; the simulated truth inside ±U (issue 11)."""
    for entry in results["scale_factor"] + results["bias"] + [results["scale_factor_ls"],
                                                              results["bias_temperature"]]:
        assert _is_number(entry["u"]) and entry["u"] > 0
        assert entry["U"] == pytest.approx(entry["k"] * entry["u"])
        # 1.645 when the table's rectangular accuracy dominates (JCGM 101 k), t(ν) otherwise
        assert 1.6 < entry["k"] < 13.0
        kinds = {line["type"] for line in entry["budget"]}
        assert "A" in kinds, entry["budget"]
    for path in ("scale_factor_ls.sf", "nonlinearity.rms_pct", "nonlinearity.max_ppm_fs",
                 "asymmetry_ppm", "sf_temperature.sensitivity_ppm_per_c",
                 "bias_temperature.sensitivity_dph_per_c"):
        assert results["uncertainty"][path]["value"] == pytest.approx(
            metric_number(results, METRICS[path]))
        assert results["uncertainty"][path]["U"] > 0
    # the table's rate accuracy from stations/sim.yaml (10 ppm rectangular) is a type B line
    sf_lines = {line["name"]: line for line in results["scale_factor"][0]["budget"]}
    assert sf_lines["table rate scale error"]["type"] == "B"
    assert sf_lines["table rate scale error"]["u_input"] == pytest.approx(10e-6 / math.sqrt(3))
    for entry in results["scale_factor"]:
        assert abs(entry["sf"] - _truth_sf(entry["sensor_temp_c"])) <= entry["U"]


def test_allan_recovers_the_angle_random_walk(results):
    # N = 0.01 deg/√h; 60 000 samples resolve it to ~2 %.
    assert results["allan"]["fit"]["N_deg_per_rth"] == pytest.approx(0.01, rel=0.1)
    assert results["allan"]["step_id"] in ("T01.static", "T02.static")


def test_acceptance_table_and_missing_metrics(results):
    names = [a["name"] for a in results["acceptance"]]
    assert names == ["SF nonlinearity (RMS)", "SF temperature instability"]
    assert all(a["pass"] for a in results["acceptance"])
    assert results["acceptance"][0]["value"] == results["nonlinearity"]["rms_pct"]
    notes: list[str] = []
    limits = [
        {"name": "tight", "metric": "nonlinearity.max_ppm_fs", "max": 1e-9, "unit": "ppm"},
        {"name": "floor", "metric": "allan.fit.N_deg_per_rth", "min": 1.0},
        {"name": "absent", "metric": "allan.fit.markov.tau_s", "max": 1000.0},
    ]
    verdicts = evaluate_acceptance(results, limits, notes)
    assert [v.decision for v in verdicts] == [Decision.FAIL] * 3
    assert [v.to_json()["pass"] for v in verdicts] == [False, False, False]
    assert verdicts[0].value == results["nonlinearity"]["max_ppm_fs"]
    assert verdicts[1].kind == "min"
    assert verdicts[2].value is None
    assert any("allan.fit.markov.tau_s" in n for n in notes)
    # a limit on a metric the catalogue does not have fails, named (an old plan.json)
    unknown = evaluate_acceptance(results, [{"name": "old", "metric": "nonlinearity.nope",
                                             "max": 1.0}], notes)
    assert unknown[0].decision is Decision.FAIL and unknown[0].value is None
    assert any("nonlinearity.nope is not a metric" in n for n in notes)


def test_journal_chain_stays_whole_after_engine_and_cli_reports(smoke_run, tmp_path):
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(smoke_run, copy)
    assert main(["report", str(copy)]) == 0
    events = [e.event for e in read_journal(copy / "journal.jsonl")]  # raises on a broken chain
    written = [e for e in events if e["event"] == "report_written"]
    assert len(written) == 2  # one by the engine, one by `gyrocal report`
    assert set(written[-1]["files"]) == {"report/results.json", "report/report.html"}


def test_one_temperature_gives_nulls_with_notes(tmp_path):
    text = (ROOT / "procedures" / "smoke.yaml").read_text()
    start = text.index("  - setpoint_c: 27.0")
    end = text.index("acceptance:")
    text = text[:start] + "\n" + text[end:]
    text = text.replace("../stations/sim.yaml", str(ROOT / "stations" / "sim.yaml"))
    text = text.replace("  - {name: SF temperature instability, metric: "
                        "sf_temperature.instability_pct, max: 1.0, unit: \"%\"}\n", "")
    procedure = tmp_path / "one-temp.yaml"
    procedure.write_text(text)
    run_dir = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--seed", "4", "--out", str(run_dir)]) == 0
    results = json.loads((run_dir / "report" / "results.json").read_text())
    assert results["sf_temperature"] is None
    assert results["bias_temperature"] is None
    assert any(n.startswith("sf_temperature") for n in results["notes"])
    assert results["scale_factor_ls"]["temp_c"] == 23.0


def test_allan_terms_carry_u_big_u_k_and_a_budget(smoke_run):
    """Issue 11: the noise terms had a 68 % interval only; now u/U/k/budget like the rest."""
    import json
    import math

    from gyrocal.metrology.gum import coverage_factor

    results = json.loads((smoke_run / "report" / "results.json").read_text())
    allan = results["allan"]
    assert allan["uncertainty"], "no Allan term got an uncertainty"
    for name, entry in allan["uncertainty"].items():
        assert entry["value"] == allan["fit"][name]
        assert entry["u"] == allan["fit_uncertainty"][name]["stderr"]
        assert entry["k"] == pytest.approx(coverage_factor(allan["fit_dof"]))
        assert entry["U"] == pytest.approx(entry["k"] * entry["u"])
        assert [line["type"] for line in entry["budget"]] == ["A"]
        assert math.isclose(results["uncertainty"][f"allan.fit.{name}"]["U"], entry["U"])


def test_report_files_are_readable_by_the_group_and_say_when_the_steps_ended(smoke_run):
    """Issue 11: mkstemp left the report 0600 (owner only), and the HTML said "ended: (report
    built before the run closed)"; a QA group reads these files and wants the date."""
    import json
    import stat as stat_mod

    for name in ("report/results.json", "report/report.html", "manifest.json"):
        mode = stat_mod.S_IMODE((smoke_run / name).stat().st_mode)
        assert mode & stat_mod.S_IRGRP and not mode & stat_mod.S_IWGRP, (name, oct(mode))
    results = json.loads((smoke_run / "report" / "results.json").read_text())
    done = results["run"]["steps_done_at"]
    assert done is not None and done.startswith(results["run"]["started_at"][:10])
    html = (smoke_run / "report" / "report.html").read_text()
    assert f"{done} (last step done" in html
    assert "report built before the run closed" not in html
