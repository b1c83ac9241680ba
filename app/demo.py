"""``gyrocal demo``: what a new user sees first, on simulated instruments only."""

from __future__ import annotations

import argparse
import datetime as dt
from pathlib import Path

from gyrocal.app.discrepancy_command import run_discrepancy
from gyrocal.app.keys import demo_keys
from gyrocal.app.requests import RunRequest
from gyrocal.app.run_commands import run
from gyrocal.errors import EXIT_ACCEPTANCE_FAILED, EXIT_FAULT
from gyrocal.record.run_folder import new_run_id
from gyrocal.record.signing import KeyPairFiles, signer_from
from gyrocal.reports.certificate import Approval, certify_run
from gyrocal.reports.verify import verify_run_folder


def cmd_demo(args: argparse.Namespace) -> int:
    """The dry run a new user sees: two acts, both against simulated instruments.

    1. The smoke procedure end to end: connect, preflight, ramp, soak, dwells,
       the report and its audit check.
    2. The discrepancy workflow: the same procedure on a station whose gyro
       carries an effect its nominal model lacks; ``gyrocal discrepancy`` with
       the nominal model must name the effect and show the gap shrink.
    """
    root = Path(__file__).resolve().parents[1]
    procedure = root / "procedures" / "smoke.yaml"
    out = Path(args.out) if args.out else Path("runs") / f"demo-{new_run_id()}"
    debug = bool(args.debug)

    print(f"== 1/2  {procedure.relative_to(root)} against simulated instruments ==")
    # A demo station key, made for this demo and kept beside its runs: it shows the
    # mechanism, not authenticity (whoever has the folder has the private key too). A real
    # station keeps its key on the station (gyrocal keys), and QA keeps the public half.
    keys = demo_keys(out / "demo-station-keys")
    print(f"demo station key {keys.fingerprint} (public half: {keys.public}; kept beside "
          "the runs, so it demonstrates signing, not authenticity)")
    code = run(RunRequest(procedure, sim=True, out=out / "smoke", speed="max", seed=1,
                          operator="demo", debug=debug, signing_key=str(keys.private)))
    if code == EXIT_FAULT:
        return code
    print(f"report: {out / 'smoke' / 'report' / 'report.html'}")
    # Certified first, verified last (below): the certificate is part of the audited history.
    certificate, number, _ = certify_run(
        out / "smoke", customer="Demo customer",
        approval=Approval("Demo approver", "Quality manager", dt.date.today()),
        signer=signer_from(keys.private))
    print(f"certificate {number}: {certificate} (SIMULATED — not a calibration)")

    hidden_code = _discrepancy_act(root, procedure, out, keys, debug)
    if hidden_code == EXIT_FAULT:
        return hidden_code

    print(f"\n== audit: gyrocal verify RUN_DIR --key {keys.public} ==")
    audits = [verify_run_folder(out / each, public_key=keys.public)
              for each in ("smoke", "hidden-effect")]
    for each in audits:
        print(each.summary() if each.ok else f"{each.run_dir}: FAILED: {each.failure}")
    if not all(each.ok for each in audits):
        return EXIT_ACCEPTANCE_FAILED
    return code


def _discrepancy_act(root: Path, procedure: Path, out: Path, keys: KeyPairFiles,
                     debug: bool) -> int:
    """Act 2: a gyro with an effect its nominal model lacks; the workflow must name it."""
    station = root / "stations" / "sim-hidden-effect.yaml"
    nominal = root / "gyro-models" / "nominal-fog.yaml"
    print(f"\n== 2/2  discrepancy: {station.relative_to(root)} carries an effect "
          f"{nominal.relative_to(root)} lacks ==")
    hidden_code = run(RunRequest(procedure, sim=True, sim_station=station,
                                 out=out / "hidden-effect", speed="max", seed=2,
                                 operator="demo", debug=debug, signing_key=str(keys.private)))
    if hidden_code == EXIT_FAULT:
        return hidden_code
    document = run_discrepancy(nominal, out / "hidden-effect", out / "discrepancy")
    for found in document["found"]:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in found["parameters"].items())
        print(f"named: {found['name']} ({params}), probability {found['probability']:.3f}")
    if not document["found"]:
        print("named: nothing")
    gap = document["gap"]
    print(f"gap ({gap['metric']}): before {gap['before']:.4g} → after {gap['after']:.4g} "
          f"(noise floor {gap['noise_floor']:.4g})")
    print(f"story: {out / 'discrepancy' / 'discrepancy.html'}")
    return hidden_code
