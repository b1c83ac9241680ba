"""Runs as a database: ten simulated calibrations of SIM-0001, indexed in place with DuckDB.

The ten runs are real dry runs (``gyrocal run --sim``, seeds 1…10) of a short
two-temperature procedure (the smoke procedure's shape with shorter holds, so
ten of them stay fast). Expected values come from each run's own
``report/results.json`` read here with ``json`` (not from the database), and
the samples view is checked against pyarrow's and Dask's reading of the same
Parquet chunks.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import matplotlib.image
import pyarrow.parquet as pq
import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main
from tests.support.short_run import without_report_figures

REPO_ROOT = Path(__file__).resolve().parents[3]
SERIAL = "SIM-0001"
RUNS = 10


def short_procedure(folder: Path) -> Path:
    text = (REPO_ROOT / "procedures" / "smoke.yaml").read_text()
    text = text.replace("station: ../stations/sim.yaml",
                        f"station: {REPO_ROOT / 'stations' / 'sim.yaml'}")
    for old, new in (("hold: 30 s", "hold: 5 s"), ("dwell: 10 s", "dwell: 4 s"),
                     ("duration: 30 s", "duration: 20 s"), ("settle: 2 s", "settle: 1 s"),
                     ("rates_dps: [10, 50, 100]", "rates_dps: [20, 60]"),
                     ("sample_rate_hz: 2000", "sample_rate_hz: 250")):
        assert old in text, old
        text = text.replace(old, new)
    assert f"serial: {SERIAL}" in text
    path = folder / "short-smoke.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("lab")
    procedure = short_procedure(root)
    with pytest.MonkeyPatch.context() as patch:
        # the runs database reads results.json and the samples, never a report's figures
        without_report_figures(patch)
        for seed in range(1, RUNS + 1):
            assert main(["run", str(procedure), "--sim", "--out",
                         str(root / "runs" / f"cal-{seed:02d}"), "--seed", str(seed)]) == EXIT_OK
    return root


def results_of(run_dir: Path) -> dict:
    return json.loads((run_dir / "report" / "results.json").read_text())


@pytest.mark.slow
def test_history_of_ten_runs_prints_the_table_and_writes_the_plot(lab: Path, capsys) -> None:
    db = lab / "runs.duckdb"
    assert main(["runs", "index", str(lab / "runs"), "--db", str(db)]) == EXIT_OK
    assert f"{RUNS} runs indexed ({RUNS} with results)" in capsys.readouterr().out
    # indexing again updates in place: still ten runs, not twenty
    assert main(["runs", "index", str(lab / "runs"), "--db", str(db)]) == EXIT_OK
    assert main(["runs", "list", "--db", str(db)]) == EXIT_OK
    listing = capsys.readouterr().out.splitlines()
    assert sum(SERIAL in line for line in listing) == RUNS

    plot = lab / "history.png"
    assert main(["history", SERIAL, "--db", str(db), "--plot", str(plot)]) == EXIT_OK
    out = capsys.readouterr().out
    lines = out.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("date (UTC)"))
    rows = lines[header + 1: header + 1 + RUNS]
    assert f"history of Simulated FOG {SERIAL}: {RUNS} calibrations" in out
    for run_dir in sorted((lab / "runs").iterdir()):
        results = results_of(run_dir)
        row = next(r for r in rows if results["run"]["run_id"] in r)
        cells = [c.strip() for c in row.split("|")]
        names = [c.strip() for c in lines[header].split("|")]
        sf = cells[names.index("sf")]
        assert float(sf.split()[0]) == pytest.approx(results["scale_factor_ls"]["sf"], rel=1e-5)
        arw = cells[names.index("arw_deg_per_rth")]
        n_fit = results["allan"]["fit"]["N_deg_per_rth"]
        assert float(arw.split()[0]) == pytest.approx(n_fit, rel=1e-5)
        big_u = results["uncertainty"]["allan.fit.N_deg_per_rth"]["U"]
        assert float(arw.split("±")[1].split()[0]) == pytest.approx(big_u, rel=0.05)
        # SF carries its expanded uncertainty too (it was NULL: history could never flag SF)
        sf_u = results["uncertainty"]["scale_factor_ls.sf"]["U"]
        assert float(sf.split("±")[1].split()[0]) == pytest.approx(sf_u, rel=0.05)
    dates = [r.split("|")[0].strip() for r in rows]
    assert dates == sorted(dates)
    image = matplotlib.image.imread(plot)
    assert image.shape[0] > 300 and image.shape[1] > 500
    assert "drift beyond uncertainty:" in out
    if os.environ.get("GYROCAL_SCREENSHOTS"):        # how docs/history-SIM-0001.png is made
        shutil.copyfile(plot, Path(os.environ["GYROCAL_SCREENSHOTS"]) / f"history-{SERIAL}.png")


def test_a_drift_beyond_uncertainty_is_flagged_and_one_within_is_not(lab: Path, tmp_path: Path,
                                                                    capsys) -> None:
    runs = sorted((lab / "runs").iterdir())
    base = results_of(runs[0])
    n = base["allan"]["fit"]["N_deg_per_rth"]
    u = base["allan"]["fit_uncertainty"]["N_deg_per_rth"]["stderr"]
    for name, shift in (("later-within", 0.5 * u), ("later-drifted", 20 * u)):
        copy = tmp_path / "runs" / name
        shutil.copytree(runs[0], copy)
        manifest = json.loads((copy / "manifest.json").read_text())
        manifest["run_id"] = name
        manifest["started_at"] = "2031-01-0" + ("1" if "within" in name else "2") + "T00:00:00+0000"
        (copy / "manifest.json").write_text(json.dumps(manifest))
        results = results_of(copy)
        results["allan"]["fit"]["N_deg_per_rth"] = n + shift
        (copy / "report" / "results.json").write_text(json.dumps(results))
    db = tmp_path / "drift.duckdb"
    assert main(["runs", "index", str(runs[0]), str(tmp_path / "runs"), "--db", str(db)]) == 0
    capsys.readouterr()
    assert main(["history", SERIAL, "--db", str(db), "--plot", str(tmp_path / "h.png")]) == 0
    out = capsys.readouterr().out
    within = next(line for line in out.splitlines() if "later-within" in line)
    drifted = next(line for line in out.splitlines() if "later-drifted" in line)
    assert " *" not in within and " *" in drifted
    assert "drift beyond uncertainty: arw_deg_per_rth" in out


def test_samples_are_queried_in_place_by_sql_and_agree_with_dask(lab: Path) -> None:
    import dask.dataframe as dd
    import duckdb

    db = lab / "runs.duckdb"
    assert main(["runs", "index", str(lab / "runs"), "--db", str(db)]) == EXIT_OK
    files = sorted((lab / "runs").glob("*/samples/*/*.parquet"))
    rows = sum(pq.ParquetFile(f).metadata.num_rows for f in files)
    con = duckdb.connect(str(db), read_only=True)
    total, runs = con.execute("SELECT count(*), count(DISTINCT run_id) FROM samples").fetchone()
    assert (total, runs) == (rows, RUNS)
    sql = dict(con.execute("""SELECT step_id, avg(gyro) FROM samples
                              WHERE step_id LIKE '%sf.+60dps' GROUP BY step_id""").fetchall())
    con.close()
    # The README's Dask example, at small scale: the same layout read by another engine.
    by_dask = {step: dd.read_parquet(str(lab / "runs" / "*" / "samples" / step / "*.parquet"),
                                     columns=["gyro"])["gyro"].mean().compute()
               for step in ("T01.sf.+60dps", "T02.sf.+60dps")}
    assert set(by_dask) == set(sql) == {"T01.sf.+60dps", "T02.sf.+60dps"}
    for step, mean in sql.items():
        assert by_dask[step] == pytest.approx(mean, rel=1e-12)
        assert mean == pytest.approx(60.0, rel=1e-3)


def test_compare_prints_both_runs_and_writes_overlays(lab: Path, tmp_path: Path, capsys) -> None:
    a, b = sorted((lab / "runs").iterdir())[:2]
    plot = tmp_path / "compare.png"
    assert main(["compare", str(a), str(b), "--plot", str(plot),
                 "--db", str(tmp_path / "none.duckdb")]) == EXIT_OK
    out = capsys.readouterr().out
    ra, rb = results_of(a), results_of(b)
    sf_line = next(line for line in out.splitlines() if line.startswith("sf "))
    cells = [c.strip() for c in sf_line.split("|")]
    assert float(cells[1].split("±")[0]) == pytest.approx(ra["scale_factor_ls"]["sf"], rel=1e-5)
    assert float(cells[2].split("±")[0]) == pytest.approx(rb["scale_factor_ls"]["sf"], rel=1e-5)
    assert float(cells[1].split("±")[1]) == pytest.approx(
        ra["uncertainty"]["scale_factor_ls.sf"]["U"], rel=0.05)
    assert float(cells[3]) == pytest.approx(rb["scale_factor_ls"]["sf"] - ra["scale_factor_ls"]["sf"],
                                            rel=1e-3, abs=1e-9)
    assert matplotlib.image.imread(plot).shape[1] > 800


def test_bad_runs_inputs_are_exit_2(tmp_path: Path, capsys) -> None:
    assert main(["history", SERIAL, "--db", str(tmp_path / "missing.duckdb")]) == EXIT_BAD_INPUT
    assert "gyrocal runs index" in capsys.readouterr().err
    assert main(["runs", "index", str(tmp_path / "nowhere")]) == EXIT_BAD_INPUT
    assert main(["compare", str(tmp_path), str(tmp_path), "--db",
                 str(tmp_path / "x.duckdb")]) == EXIT_BAD_INPUT
    assert "neither a run folder nor a run id" in capsys.readouterr().err


def _copy_run(source: Path, target: Path, run_id: str, started_at: str,
              edit: Callable[[dict], None]) -> None:
    shutil.copytree(source, target)
    manifest = json.loads((target / "manifest.json").read_text())
    manifest["run_id"] = run_id
    manifest["started_at"] = started_at
    results = results_of(target)
    edit(results)
    manifest["unit_under_test"] = results["unit_under_test"]
    (target / "manifest.json").write_text(json.dumps(manifest))
    (target / "report" / "results.json").write_text(json.dumps(results))


def test_every_metric_with_an_uncertainty_stores_it_and_bias_is_at_the_reference_temperature(
        lab: Path, tmp_path: Path) -> None:
    import duckdb

    run = sorted((lab / "runs").iterdir())[0]
    db = tmp_path / "one.duckdb"
    assert main(["runs", "index", str(run), "--db", str(db)]) == EXIT_OK
    con = duckdb.connect(str(db), read_only=True)
    stored = {m: (v, u, big_u) for m, v, u, big_u in con.execute(
        "SELECT metric, value, u, expanded_u FROM metrics").fetchall()}
    con.close()
    results = results_of(run)
    budget = results["uncertainty"]
    for metric, key in (("sf", "scale_factor_ls.sf"), ("asymmetry_ppm", "asymmetry_ppm"),
                        ("sf_tempco_ppm_per_c", "sf_temperature.sensitivity_ppm_per_c"),
                        ("bias_tempco_dph_per_c", "bias_temperature.sensitivity_dph_per_c"),
                        ("nonlinearity_rms_pct", "nonlinearity.rms_pct"),
                        ("nonlinearity_max_ppm_fs", "nonlinearity.max_ppm_fs")):
        value, u, big_u = stored[metric]
        assert (u, big_u) == (pytest.approx(budget[key]["u"]), pytest.approx(budget[key]["U"])), \
            metric
        assert big_u > 0
    # the smoke procedure measures the bias at 23 and 27 °C; the reference temperature is 25 °C,
    # half-way: the headline is their mean, not the bias at the first temperature
    assert results["reference_temp_c"] == 25.0
    at = {b["temp_c"]: b for b in results["bias"]}
    assert sorted(at) == [23.0, 27.0]
    value, u, big_u = stored["bias_dph"]
    assert value == pytest.approx(0.5 * (at[23.0]["bias_dph"] + at[27.0]["bias_dph"]))
    assert value != pytest.approx(at[23.0]["bias_dph"])
    assert u == pytest.approx(0.5 * (at[23.0]["u"] + at[27.0]["u"]))
    assert big_u == pytest.approx(0.5 * (at[23.0]["U"] + at[27.0]["U"]))


def test_sf_drift_is_judged_against_its_uncertainty(lab: Path, tmp_path: Path, capsys) -> None:
    """A 0.3 U change of SF is not a drift; 20 U is, flagged against √(U² + U₀²)."""
    first = sorted((lab / "runs").iterdir())[0]
    big_u = results_of(first)["uncertainty"]["scale_factor_ls.sf"]["U"]

    def shifted(by: float) -> Callable[[dict], None]:
        def edit(results: dict) -> None:
            results["scale_factor_ls"]["sf"] += by
            results["uncertainty"]["scale_factor_ls.sf"]["value"] += by
        return edit

    _copy_run(first, tmp_path / "runs" / "a", "sf-within", "2031-01-01T00:00:00+0000",
              shifted(0.3 * big_u))
    _copy_run(first, tmp_path / "runs" / "b", "sf-drifted", "2031-01-02T00:00:00+0000",
              shifted(20 * big_u))
    db = tmp_path / "sf.duckdb"
    assert main(["runs", "index", str(first), str(tmp_path / "runs"), "--db", str(db)]) == 0
    capsys.readouterr()
    plot = tmp_path / "h.png"
    assert main(["history", SERIAL, "--db", str(db), "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    header = next(line for line in lines if line.startswith("date (UTC)"))
    sf_column = [c.strip() for c in header.split("|")].index("sf")
    within = next(line for line in lines if "sf-within" in line).split("|")[sf_column]
    drifted = next(line for line in lines if "sf-drifted" in line).split("|")[sf_column]
    assert "±" in within and not within.strip().endswith("*")
    assert drifted.strip().endswith("*")
    assert "drift beyond uncertainty: sf" in out
    assert matplotlib.image.imread(plot).shape[0] > 300


def test_a_unit_is_its_model_and_serial(lab: Path, tmp_path: Path, capsys) -> None:
    """Another model with the same serial is another gyro, never more calibrations of this one."""
    runs = sorted((lab / "runs").iterdir())[:2]

    def other_model(results: dict) -> None:
        results["unit_under_test"]["model"] = "Other FOG"

    _copy_run(runs[0], tmp_path / "runs" / "other", "other-model", "2031-01-01T00:00:00+0000",
              other_model)
    db = tmp_path / "units.duckdb"
    assert main(["runs", "index", *map(str, runs), str(tmp_path / "runs"), "--db", str(db)]) == 0
    capsys.readouterr()
    assert main(["history", SERIAL, "--db", str(db)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert f"{SERIAL} is the serial of 2 units" in err and "'Other FOG'" in err
    assert "'Simulated FOG'" in err and "--model" in err
    plot = str(tmp_path / "h.png")
    assert main(["history", SERIAL, "--model", "Simulated FOG", "--db", str(db), "--plot",
                 plot]) == 0
    out = capsys.readouterr().out
    assert f"history of Simulated FOG {SERIAL}: 2 calibrations" in out and "other-model" not in out
    assert main(["history", SERIAL, "--model", "Other FOG", "--db", str(db), "--plot",
                 plot]) == 0
    out = capsys.readouterr().out
    assert f"history of Other FOG {SERIAL}: 1 calibrations" in out and "other-model" in out
