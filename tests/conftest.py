"""Fixtures shared by every test folder."""

from __future__ import annotations

import os
import signal
import sys

import pytest

# The Allan kernel runs in numba's OpenMP threads (analysis/allan/kernel.py). GNU OpenMP's
# default lets a region's threads spin after it ends, waiting for the next one: ~24 ms of
# CPU a curve, against ~5 ms of work for a report's 2,000-sample static (measured: 29.4 ->
# 5.3 ms CPU an allan_curve). Under `make test` four workers share two cores and every run
# builds a report, so that spinning only takes CPU from the other workers. Passive waiting
# changes no number (the threads compute the same tiles; the wait policy is how they idle).
# Set before anything loads libgomp; the processes the tests start inherit it.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# OpenBLAS likewise starts a thread a core and spins it between calls. The suite runs two
# workers a core, so a second BLAS thread never has a core of its own: one thread a process,
# as the discrepancy workflow already runs its own BLAS (analysis/discrepancy/workflow.py).
# Measured on test_process_shape.py + test_stochastic.py: 64.1 -> 36.4 s CPU, same outcomes.
# The variable is read when numpy loads; if a plugin loaded numpy first, the limit is set
# in this process by threadpoolctl instead (the processes the tests start read the variable).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
if "numpy" in sys.modules:
    from threadpoolctl import threadpool_limits

    _BLAS_LIMIT = threadpool_limits(limits=int(os.environ["OPENBLAS_NUM_THREADS"]), user_api="blas")

# A suite started in the background by a non-interactive shell (`nohup make test &`, a CI
# runner's job) inherits SIGINT ignored, and the processes the tests start would inherit
# that too: `gyrocal sim serve` and `watch` would not stop on the Ctrl-C the tests send, and
# a run would not see the SIGINT its signal tests deliver. A handler installed here is reset
# to the default on exec, so every process the suite starts reacts to Ctrl-C as on a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session", autouse=True)
def session_lock_dir(tmp_path_factory):
    """Station locks private to this test session (and the processes it starts).

    Locks are keyed on the instrument (its resolved address, its reported serial),
    and every ``gyrocal sim serve`` reports the same simulated serials: two test
    sessions on one machine must not refuse each other's simulated stations.
    """
    import os

    from gyrocal.record.locks import LOCK_DIR_ENV

    previous = os.environ.get(LOCK_DIR_ENV)
    os.environ[LOCK_DIR_ENV] = str(tmp_path_factory.mktemp("station-locks"))
    yield os.environ[LOCK_DIR_ENV]
    if previous is None:
        os.environ.pop(LOCK_DIR_ENV, None)
    else:
        os.environ[LOCK_DIR_ENV] = previous


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory, worker_id):
    """One dry run of procedures/smoke.yaml for the whole session (tests copy it to tamper).

    Read-only to every test (a test that changes a run copies it first). Under pytest-xdist
    the workers share one: the first to ask makes it in the session's common temporary
    folder, under a file lock, and the others wait for it and read it (the modules that
    use it land on three workers of four under ``make test``: two smoke runs fewer).
    """
    import fcntl
    from pathlib import Path

    from gyrocal.cli import main

    root = Path(__file__).resolve().parents[1]
    base = tmp_path_factory.getbasetemp()
    shared = base if worker_id == "master" else base.parent     # xdist: <session temp>/popen-gwN
    run_dir = shared / "smoke-run"
    with open(shared / "smoke-run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (shared / "smoke-run.made").is_file():
            code = main(["run", str(root / "procedures" / "smoke.yaml"), "--sim", "--seed", "3",
                         "--out", str(run_dir), "--operator", "qa-test"])
            assert code == 0
            (shared / "smoke-run.made").write_text(worker_id)
    return run_dir


def pytest_collection_modifyitems(config, items):
    """Modules holding a ``slow`` test run first, each module kept together.

    ``make test`` spreads the modules over worker processes (pytest-xdist,
    ``--dist loadscope``: a module's fixtures are built once, on one worker); the long
    end-to-end modules started first leave the short ones to fill the gaps at the end,
    instead of one of them starting last and running alone. The order within a
    module, and among the other modules, stays as collected.
    """
    slow_modules = {item.nodeid.split("::")[0] for item in items
                    if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in slow_modules)
