"""``gyrocal verify`` on a report an older gyrocal built (issue 28).

verify recomputes the report's numbers with the code that runs it. A report
built before a key existed then failed on that key alone, although nothing in it
was wrong. Here an older gyrocal is played by the report rebuild with a key left
out of its results, signed and journaled by the product's own rebuild path (so
the history, the hashes and the signature are all proper): verify passes and
names the key it could not compare; a changed value, signed just as properly,
still fails.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from gyrocal.cli import main
from gyrocal.record.signing import generate_key_pair
from gyrocal.reports.results import Results

pytestmark = pytest.mark.timeout(300)
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    return generate_key_pair(tmp_path_factory.mktemp("station-keys"))


@pytest.fixture(scope="module")
def signed_original(tmp_path_factory, keys) -> Path:
    """One signed smoke run for the module; each test takes a copy (signed_run)."""
    out = tmp_path_factory.mktemp("signed") / "run"
    assert main(["run", str(ROOT / "procedures/smoke.yaml"), "--sim", "--seed", "3",
                 "--out", str(out), "--signing-key", str(keys.private)]) == 0
    return out


@pytest.fixture
def signed_run(signed_original: Path, tmp_path: Path) -> Path:
    """A copy of the module's signed run, for this test to rebuild and verify. The run is
    the same for every test (one seed, one key); a copy, not a run of its own per test,
    saves two smoke runs (~3 s of CPU each), and a test's rebuild never reaches another's."""
    out = tmp_path / "run"
    shutil.copytree(signed_original, out)
    return out


def _rebuild_with(run: Path, keys, edit, monkeypatch: pytest.MonkeyPatch) -> None:
    """``gyrocal report RUN_DIR`` (signed, journaled, sealed) with ``edit`` applied to the
    results.json object it states, as a gyrocal that wrote them so would have."""
    real = Results.to_json

    def older(self: Results) -> dict:
        results = real(self)
        edit(results)
        return results

    with monkeypatch.context() as patch:
        patch.setattr(Results, "to_json", older)
        assert main(["report", str(run), "--signing-key", str(keys.private)]) in (0, 1)


def test_a_key_the_older_report_lacks_is_named_not_failed(signed_run: Path, keys, capsys,
                                                           monkeypatch: pytest.MonkeyPatch):
    def drop(results):
        assert "max_ppm_fs" in results["nonlinearity"]
        del results["nonlinearity"]["max_ppm_fs"]

    _rebuild_with(signed_run, keys, drop, monkeypatch)
    capsys.readouterr()
    assert main(["verify", str(signed_run), "--key", str(keys.public)]) == 0
    out = capsys.readouterr().out
    assert "not in this report (older gyrocal), not compared: nonlinearity.max_ppm_fs" in out
    assert "authentic: 2 seal(s) verified with the given key" in out   # run + rebuild


def test_a_changed_value_in_a_properly_signed_report_still_fails(
        signed_run: Path, keys, capsys, monkeypatch: pytest.MonkeyPatch):
    def change(results):
        results["nonlinearity"]["rms_pct"] = results["nonlinearity"]["rms_pct"] * 1.01

    _rebuild_with(signed_run, keys, change, monkeypatch)
    capsys.readouterr()
    assert main(["verify", str(signed_run), "--key", str(keys.public)]) == 1
    err = capsys.readouterr().err
    assert "nonlinearity.rms_pct is" in err and "the report does not follow from the samples" in err


def test_an_untouched_report_compares_every_key(signed_run: Path, keys, capsys):
    capsys.readouterr()
    assert main(["verify", str(signed_run), "--key", str(keys.public)]) == 0
    assert "not in this report" not in capsys.readouterr().out
