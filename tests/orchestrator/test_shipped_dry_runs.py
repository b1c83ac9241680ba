"""The shipped procedures' seeded dry runs: the same twice, the same killed and resumed (issue 30).

Two checks per shipped procedure, both against one uninterrupted reference run
made once per procedure (a class-scoped fixture) instead of once per check:

* **identical twice** — a second uninterrupted run with the seed writes the
  same samples, journal and results.json (``tests/support/dry_run_compare.py``
  says apart from what). Guards against randomness not derived from (seed,
  step id, attempt) and simulated time moved by thread scheduling instead of the
  controller's calls. Here the procedures whose dry run takes seconds, one per
  kind of simulated station; every shipped procedure in full:
  ``benchmarks/check_dry_run_determinism.py`` (docs/dry-run-determinism.md).
* **killed and resumed** — the run killed by SIGKILL at a journal boundary
  where its simulators hold state (``GYROCAL_CRASH_AT``), then ``gyrocal
  resume`` (which takes the seed the run started with), counts the reference's
  samples value for value and the same numbers in results.json
  (``assert_resumed_equal``). Guards against a simulator whose state is not in
  the station's snapshot or not put back by ``restore`` (the resumed run would
  go on from a fresh simulator: other noise, another mounting, another supply
  output). The single-axis station and every boundary of a short run:
  test_resumed_dry_run_equal.py and test_crash_every_boundary.py.

The SCPI gyros' reference runs also serve their end-to-end checks: the KVG25's
V per deg/s and the RLG's scale factor (in whole pulses) recovered within the
reported uncertainty, the input chain named in the report and the certificate
(formerly test_analog_gyro_dry_run.py, which made an unseeded run of each of its
own in a subprocess); the acceptance series' reference, each covered test's truth
recovered within U (formerly test_acceptance_series.py, its own run).

Each procedure is a class: pytest-xdist's ``loadscope`` keeps a class on one
worker (its reference made once there) and spreads the classes over the workers.
The in-process runs build their reports without the Matplotlib figures
(``without_report_figures``: about half of a short run's CPU time; neither check
reads them; the figures are drawn by every other dry run of the suite).
The IMU procedure is run cut to its first three temperatures, with shorter holds
(``TestImuMountings``).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from pypdf import PdfReader

from gyrocal.cli import EXIT_OK, main
from gyrocal.record.crash import CRASH_AT_ENV
from gyrocal.record.run_folder import RunFolder
from tests.support.dry_run_compare import (
    assert_resumed_equal,
    columns,
    counted_samples,
    differences,
    results,
)
from tests.support.fork_server import ForkServer
from tests.support.short_run import without_report_figures

REPO = Path(__file__).resolve().parents[2]
SEED = "11"

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]


@dataclass(frozen=True)
class Reference:
    """The uninterrupted run of one procedure and what the checks compare with it."""

    procedure: Path
    path: Path
    code: int
    events: list[dict[str, Any]]
    samples: dict[str, tuple[int, dict[str, Any]]]
    results: dict[str, Any]

    @property
    def plan(self) -> list[str]:
        """The steps completed, in order."""
        return [e["step_id"] for e in self.events if e["event"] == "step_completed"]


@pytest.fixture(scope="class")
def no_figures() -> Iterator[None]:
    """The in-process runs of a class build their reports without figures."""
    with pytest.MonkeyPatch.context() as patch:
        without_report_figures(patch)
        yield


class _Shipped:
    """One shipped procedure (``name``) and its reference run."""

    name: str = ""

    @classmethod
    def procedure(cls, folder: Path) -> Path:
        """The procedure file the runs take: the shipped one unless a class cuts it."""
        return REPO / "procedures" / f"{cls.name}.yaml"

    @staticmethod
    def run_args(procedure: Path, out: Path) -> list[str]:
        return ["run", str(procedure), "--sim", "--seed", SEED, "--out", str(out),
                "--allow-outside-paths"]

    @pytest.fixture(scope="class")
    @classmethod
    def reference(cls, tmp_path_factory, no_figures) -> Reference:
        folder = tmp_path_factory.mktemp(cls.name)
        procedure = cls.procedure(folder)
        path = folder / "reference"
        code = main(cls.run_args(procedure, path))
        assert code in (EXIT_OK, 1)
        return Reference(procedure, path, code, RunFolder.open(path).journal_events(),
                         counted_samples(path), results(path))


class _IdenticalTwice(_Shipped):
    def test_two_runs_with_one_seed_are_identical(self, reference: Reference, tmp_path: Path,
                                                  no_figures) -> None:
        second = tmp_path / "second"
        assert main(self.run_args(reference.procedure, second)) in (0, 1)
        assert len(columns(reference.path)) >= 10
        assert reference.results["run"]["run_id"] != results(second)["run"]["run_id"]
        assert differences(reference.path, second) == []


def certificate_text(run: Path, tmp_path: Path) -> str:
    """The certificate `gyrocal certificate` writes for a copy of ``run`` (the reference
    stays as the run left it), as text."""
    copy = tmp_path / "certified"
    shutil.copytree(run, copy)
    assert main(["certificate", str(copy), "--customer", "ACME",
                 "--approved-by", "A. Auditor"]) == 0
    pages = PdfReader(copy / "report" / "certificate.pdf").pages
    return " ".join(" ".join(page.extract_text() for page in pages).split())


def _seq(events: list[dict[str, Any]], event: str, step_id: str) -> int:
    return next(e["seq"] for e in events if e["event"] == event and e.get("step_id") == step_id)


class _KilledAndResumed(_Shipped):
    """``kills(events)``: where to kill (name → ``before:SEQ``/``after:SEQ``), among
    mid-step (``cut`` is run again as a new attempt), between a step that acts after its
    step_completed line and the next (after its act and the state journaled then), and in
    between (the act done, its state not yet journaled)."""

    cut: str = ""
    kills: Callable[[list[dict[str, Any]]], dict[str, str]]

    def test_killed_and_resumed_equals_uninterrupted(self, reference: Reference,
                                                     tmp_path: Path, capsys, no_figures,
                                                     fork_server: ForkServer) -> None:
        # every step's state is journaled: on its step_completed line or after its act
        with_state = {e["step_id"] for e in reference.events if "sim_state" in e
                      and e["event"] in ("step_completed", "sim_state_saved")}
        assert with_state == set(reference.plan)
        for point_name, point in self.kills(reference.events).items():
            out = tmp_path / point_name
            status = fork_server.run(self.run_args(reference.procedure, out),
                                     {CRASH_AT_ENV: point}, tmp_path / f"{point_name}.err",
                                     figures=False)
            assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (
                point_name, status)
            capsys.readouterr()
            assert main(["resume", str(out)]) in (0, 1), (point_name, capsys.readouterr())
            assert_resumed_equal(out, point_name, reference.samples, reference.results,
                                 reference.plan, self.cut)


class TestSmoke(_IdenticalTwice):
    """The single-axis STIM300 station. Its reference is the session's smoke run
    (conftest.py, made once per worker for the report tests), so its arguments and
    its figures are that run's."""

    name = "smoke"

    @staticmethod
    def run_args(procedure: Path, out: Path) -> list[str]:
        return ["run", str(procedure), "--sim", "--seed", "3", "--out", str(out),
                "--operator", "qa-test"]

    @pytest.fixture(scope="class")
    @classmethod
    def reference(cls, smoke_run: Path) -> Reference:
        return Reference(REPO / "procedures" / "smoke.yaml", smoke_run, EXIT_OK,
                         RunFolder.open(smoke_run).journal_events(), {}, results(smoke_run))

    @pytest.fixture(scope="class")
    @classmethod
    def no_figures(cls) -> None:
        """Drawn, as in the session's smoke run."""


class TestMagneticSensitivity(_IdenticalTwice, _KilledAndResumed):
    """The supply's coil channels, the powered unit, the Faraday effect."""

    name = "magnetic-sensitivity"
    cut = "T01.mag.zero"

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"mid-step": f"before:{_seq(ev, 'step_completed', 'T01.mag.zero')}",
                "after-act": f"after:{_seq(ev, 'sim_state_saved', 'T01.mag.pos')}",
                "before-state-saved": f"before:{_seq(ev, 'sim_state_saved', 'T01.mag.pos')}"}


class TestTableInterference(_IdenticalTwice, _KilledAndResumed):
    """The table's drive off (interlock open) after a powered static."""

    name = "table-interference"
    cut = "T01.interference.off"

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"mid-step": f"before:{_seq(ev, 'step_completed', 'T01.interference.off')}"}


class TestKvg25AnalogDmm(_IdenticalTwice, _KilledAndResumed):
    """The analog gyro through a SCPI DMM: its reading memory and sample timer."""

    name = "kvg25-analog-dmm"
    cut = "T01.sf.+50dps"

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"mid-step": f"before:{_seq(ev, 'step_completed', 'T01.sf.+50dps')}"}

    def test_the_run_recovers_the_models_volts_per_dps_within_u(self, reference: Reference,
                                                                tmp_path: Path) -> None:
        """The simulated 34465A samples the gyro model's volts on its sample timer: the
        model's SF at the LS-line temperature, 0.025 V/(deg/s) at 25 °C with 20 ppm/°C
        (gyro-models/kvg25-analog.yaml, typed), lies inside the reported U; the report
        and the certificate say the chain was analog."""
        fit = reference.results["scale_factor_ls"]
        truth = 0.025 * (1 + 20e-6 * (fit["temp_c"] - 25.0))
        assert abs(fit["sf"] - truth) <= fit["U"], (fit["sf"], truth, fit["U"])
        assert fit["U"] < 1e-5 * 0.025 * 100          # a meaningful bound: under 0.1 % of the SF
        gyro = reference.results["instruments"]["gyro"]
        assert gyro["driver"] == "keysight_34465a"
        assert gyro["description"].startswith("analog input chain: DC volts through")
        html = next((reference.path / "report").glob("*.html")).read_text()
        assert "analog input chain" in html
        reads = [e for e in reference.events if e["event"] == "supply_read"]
        assert reads and all(r["ok"] and r["voltage_v"] == 12.0 for r in reads)
        text = certificate_text(reference.path, tmp_path)
        assert "Input chain keysight_34465a: analog input chain: DC volts through" in text


class TestRlgPulseCounter(_IdenticalTwice, _KilledAndResumed):
    """The RLG through a SCPI counter: its gates and the pulse phase carried between them."""

    name = "rlg-pulse-counter"
    cut = "T01.sf.+50dps"

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"mid-step": f"before:{_seq(ev, 'step_completed', 'T01.sf.+50dps')}"}

    def test_the_dithered_rlg_recovers_its_scale_factor_in_whole_pulses(self,
                                                                       reference: Reference,
                                                                       tmp_path: Path) -> None:
        """SF = 1 + 5 ppm + 0.1 ppm/°C·(T − 25) (the model's sf_error and tempco) inside U;
        every logged readout is a whole number of 2-arcsec pulses."""
        fit = reference.results["scale_factor_ls"]
        truth = 1.0 + 5e-6 + 0.1e-6 * (fit["temp_c"] - 25.0)
        assert abs(fit["sf"] - truth) <= fit["U"], (fit["sf"], truth, fit["U"])
        assert reference.results["instruments"]["gyro"]["description"].startswith(
            "pulse input chain")
        assert ("Input chain keysight_53230a: pulse input chain: timed totalize"
                in certificate_text(reference.path, tmp_path))
        pulses_per_dps = 1.0 / ((2.0 / 3600.0) * 200.0)        # one readout of 5 ms
        chunks = sorted((reference.path / "samples" / "T01.static").glob("*.parquet"))
        assert chunks
        for chunk in chunks:
            gyro = pq.read_table(chunk, columns=["gyro"]).column("gyro").to_numpy()
            pulses = gyro * pulses_per_dps
            assert np.allclose(pulses, np.round(pulses), atol=1e-6)
            assert len(np.unique(np.round(pulses))) >= 2       # the count steps by one pulse


#: tilt-linearity.yaml's holds, shortened for its kill-and-resume check (steps unchanged)
def _cut(text: str, replacements: tuple[tuple[str, str], ...]) -> str:
    """``text`` with each (old, new) replaced; each old must occur once (else the shipped file changed: update the cut)."""
    for old, new in replacements:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text


TILT_SHORTER = (("station: ../stations/", f"station: {REPO}/stations/"),
                ("hold: 10 min", "hold: 1 min"),
                ("zero_stability: 1 h", "zero_stability: 3 min"),
                ("zero_stability: 10 min", "zero_stability: 3 min"))


class TestTiltLinearity(_KilledAndResumed):
    """The table on its side in position mode, the inclinometers' noise; the last tilt of
    a run of them returns the table to 0 deg and rate mode after its step_completed line."""

    name = "tilt-linearity"
    cut = "T01.tilt2.-25deg"

    @classmethod
    def procedure(cls, folder: Path) -> Path:
        """The shipped file with shorter holds: its 1-h and 10-min zero stabilities and
        its 10-min soak are 2/3 of its samples, and what is checked (every step and kill
        point, each step's state restored, the same samples and results) does not need
        them long. Every step of the shipped plan stays, in order."""
        text = super().procedure(folder).read_text()
        text = _cut(text, TILT_SHORTER)
        path = folder / f"{cls.name}-short-holds.yaml"
        path.write_text(text)
        return path

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"mid-step": f"before:{_seq(ev, 'step_completed', 'T01.tilt2.-25deg')}",
                "before-state-saved": f"before:{_seq(ev, 'sim_state_saved', 'T01.tilt1.zero')}"}


#: the acceptance series' truths, typed from gyro-models/series-fog.yaml and
#: stations/sim-series.yaml (not read from them) or worked by hand
DEAD_ZONE_DPS = 0.025     # typed from gyro-models/series-fog.yaml, not read from it
SATURATION_DPS = {"positive": 320.0, "negative": 270.0}
BANDWIDTH_HZ = 1.0        # rate_bandwidth, typed
PHASE_AT_HALF_HZ_DEG = -26.565051177   # −atan(0.5 / 1.0) in degrees, worked by hand
STARTUP_S = 0.8           # stations/sim-series.yaml simulation.gyro_startup_s, typed
WARMUP_TAU_S, WARMUP_DPH = 10.0, 20.0   # warmup_transient, typed
TIME_TO_BAND_S = 29.957322736          # 10 s · ln(20 / 1 deg/h), worked by hand
# simulation.turn_on_bias_dph 2.0 (1 σ per power-on), typed; each cycle's 10-s mean adds the
# white noise 0.6 deg/h/√Hz / √10 s = 0.19 deg/h: √(2² + 0.19²) = 2.009 deg/h
REPEATABILITY_DPH = 2.009


class TestAcceptanceSeries(_KilledAndResumed):
    """Frequency response (synthesis mode left after step_completed), a powered unit's
    turn-on cycles (the supply, the start-up delay, each power-on's bias draw)."""

    name = "acceptance-series"
    cut = "T01.rep.c3"

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"before-state-saved": f"before:{_seq(ev, 'sim_state_saved', 'T01.freq.2Hz')}",
                "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.rep.c3')}"}

    def test_the_series_recovers_each_truth(self, reference: Reference) -> None:
        """Each covered test recovers the simulated gyro's hand-typed truth
        (gyro-models/series-fog.yaml) within its reported uncertainty (formerly
        test_acceptance_series.py, which made a run of its own)."""
        assert reference.code == EXIT_OK
        results = reference.results
        zero = next(t for t in results["threshold"]["tests"] if t["base_rate_dps"] == 0)
        assert zero["standard_test"] == "threshold (IEEE Std 952 / 1431)"
        assert zero["below_dps"] < DEAD_ZONE_DPS <= zero["threshold_dps"]
        assert abs(zero["estimate_dps"] - DEAD_ZONE_DPS) <= zero["U_dps"]
        assert results["threshold"]["resolution_dps"] == 0.01
        for walk in results["rate_limits"]["tests"]:
            truth = SATURATION_DPS[walk["direction"]]
            assert walk["max_dps"] <= truth < walk["next_dps"], walk
            assert abs(walk["estimate_dps"] - truth) <= walk["U_dps"]
            assert walk["next_dps"] - walk["max_dps"] == 50.0
        assert (results["rate_limits"]["max_positive_dps"],
                results["rate_limits"]["max_negative_dps"]) == (300.0, 250.0)
        response = results["frequency_response"]
        test = response["tests"][0]
        assert test["standard_test"] == "frequency response (IEEE Std 952 / 1431)"
        assert abs(response["bandwidth_hz"] - BANDWIDTH_HZ) <= test["U_bandwidth_hz"]
        assert 0 < test["U_bandwidth_hz"] < 0.01
        assert abs(response["phase_deg"] - PHASE_AT_HALF_HZ_DEG) <= test["U_phase_deg"]
        one_hz = next(p for p in test["points"] if p["freq_hz"] == 1.0)
        assert one_hz["gain_db"] == pytest.approx(-3.0103, abs=0.01)     # 1/√2 at the corner
        assert results["uncertainty"]["frequency_response.bandwidth_hz"]["U"] == \
            test["U_bandwidth_hz"]
        turn_on = results["turn_on"]["tests"][0]
        # the first frame is the first on the 250 Hz grid at or after output-on + 0.8 s: within
        # 4 ms of 0.8 s, inside U (0.02 s poll: U = 2·0.02/√12 = 0.0115 s)
        assert (abs(turn_on["time_to_first_data_s"] - STARTUP_S)
                <= turn_on["U_time_to_first_data_s"])
        assert abs(turn_on["warmup_tau_s"] - WARMUP_TAU_S) <= turn_on["U_warmup_tau_s"], turn_on
        assert (abs(turn_on["warmup_amplitude_dph"] - WARMUP_DPH)
                <= turn_on["U_warmup_amplitude_dph"])
        assert abs(turn_on["time_to_band_s"] - TIME_TO_BAND_S) <= turn_on["U_time_to_band_s"]
        assert turn_on["U_warmup_tau_s"] < 1.0
        assert results["uncertainty"]["turn_on.warmup_tau_s"]["U"] == turn_on["U_warmup_tau_s"]
        journal = (reference.path / "journal.jsonl").read_text().splitlines()
        cycles = [json.loads(line) for line in journal if '"unit_power_cycle"' in line]
        assert [c["step_id"] for c in cycles][0] == turn_on["step_id"]
        rep = results["turn_on_repeatability"]["tests"][0]
        assert rep["cycles"] == 8 and len(set(rep["biases_dph"])) == 8
        assert abs(rep["std_dph"] - REPEATABILITY_DPH) <= rep["U_std_dph"], rep
        assert rep["u_std_dph"] == pytest.approx(rep["std_dph"] / 14 ** 0.5)     # s/√(2(N−1))
        assert 0.5 < rep["in_run_std_dph"] < 0.8      # 1-s means of 0.6 deg/h/√Hz white noise
        assert [c["step_id"] for c in cycles][1:] == [f"T01.rep.c{n}" for n in range(1, 9)]
        assert [a["decision"] for a in results["acceptance"]] == ["PASS"] * 10
        html = (reference.path / "report" / "report.html").read_text()
        assert "<h2>Threshold and resolution (IEEE Std 952 / IEEE Std 1431)</h2>" in html
        assert "0.03 (in (0.02, 0.03])" in html
        assert "<h2>Input rate limits (IEEE Std 952 / IEEE Std 1431)</h2>" in html
        assert "300 (limit in [300, 350))" in html
        assert "<h2>Frequency response (IEEE Std 952 / IEEE Std 1431)</h2>" in html
        assert "<h2>Turn-on time and warm-up (IEEE Std 952 / IEEE Std 1431)</h2>" in html
        assert ("<h2>Turn-on-to-turn-on bias repeatability (IEEE Std 952 / IEEE Std 1431)</h2>"
                in html)
        synthesis = [json.loads(line) for line in journal if '"table_synthesis"' in line]
        assert [e["freq_hz"] for e in synthesis] == [0.25, 0.5, 0.75, 0.9, 1.0, 1.1, 1.25, 1.5,
                                                     2.0]
        # TM-8004 §4.3.4: the oscillator takes the peak displacement, 1 deg/s / (2π · 0.25 Hz)
        assert synthesis[0]["displacement_deg"] == pytest.approx(0.636619772, abs=1e-9)


#: the IMU procedure's temperatures after the first three, cut from its sequence
IMU_LATER_TEMPERATURES = ("  - {setpoint_c: 30.0, tests: *point}\n",
                          "  - {setpoint_c: 40.0, tests: *point}\n")
#: its holds, shortened (every step kept, in order; each sweep dwell still whole revolutions,
#: at least two): what the simulated time costs is instrument polling and pty frames, not
#: a path of its own. The static stays 2 min so that each is still written in more than
#: one chunk (a chunk a minute): the killed attempt leaves several to set aside.
IMU_SHORTER = (("duration: 5 min", "duration: 2 min"), ("hold: 30 min", "hold: 1 min"),
               ("dwell: 1 min", "dwell: 10 s"), ("settle: 15 s", "settle: 5 s"))


class TestImuMountings(_KilledAndResumed):
    """Three axes on the fixture, killed in its second mounting: each axis's state (noise,
    Markov, walk and thermal levels) and the accelerometers' stream restored. (The
    mounting itself the simulated operator turns back to on resume, as a person would
    confirm it: remount.SimulatedFixtureOperator.resumed.)

    Cut to its first three temperatures (-10, 5, 20 °C): the kill lands where it does in
    the full procedure (T01, mounting Y, after the remount from X), the resumed session
    then remounts Z, Xdown, Ydown, Zdown and changes temperature twice, and three
    temperatures are the fewest for which the report fits its compensation tables (its
    every section present); the fourth and fifth add only more of the same, ~5 s of CPU
    each per run. Its holds are shortened (``IMU_SHORTER``; the same 222 steps, the same
    results.json sections and verdicts, measured: 13.3 -> 8.7 s CPU a run, each run of
    the class: the reference, the killed one and its resume).
    """

    name = "imu-5-temps-3-mountings"
    cut = "T01.MY.static"

    @classmethod
    def procedure(cls, folder: Path) -> Path:
        text = super().procedure(folder).read_text()
        for line in (*IMU_LATER_TEMPERATURES, "station: ../stations/"):
            assert line in text, line        # the shipped file changed: update the cut
        text = text.replace("station: ../stations/", f"station: {REPO}/stations/")
        for line in IMU_LATER_TEMPERATURES:
            text = text.replace(line, "")
        text = _cut(text, IMU_SHORTER)
        path = folder / f"{cls.name}-3-temps.yaml"
        path.write_text(text)
        return path

    @staticmethod
    def kills(ev: list[dict[str, Any]]) -> dict[str, str]:
        return {"mid-step": f"before:{_seq(ev, 'step_completed', 'T01.MY.static')}"}

    def test_the_cut_keeps_three_temperatures_and_every_mounting(self,
                                                                 reference: Reference) -> None:
        plan = reference.plan
        assert {step.split(".")[0] for step in plan} == {"T01", "T02", "T03"}
        assert {step.split(".")[1] for step in plan if step.endswith(".static")} == {
            "MX", "MY", "MZ", "MXdown", "MYdown", "MZdown"}
        tables = reference.results["compensation"]["tables"]
        assert tables["sf"]["piecewise_linear"] is not None
        # the killed step is written in several chunks (the shortened static still is)
        assert sum(1 for e in reference.events if e["event"] == "chunk_written"
                   and e.get("step_id") == self.cut) >= 2
