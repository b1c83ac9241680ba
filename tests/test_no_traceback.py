"""No traceback, and the right exit code, for every input (issue 9, defect 3).

The named reproducers of the adversarial pass: each one ended in a traceback,
a hang or exhausted memory on the old main. Each case runs the real command
line and asserts the exit code, that the message names the file (and line
where there is one), and that no traceback is printed. A hypothesis property
test then throws generated documents at every YAML input kind.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gyrocal.cli import EXIT_ACCEPTANCE_FAILED, EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main

REPO = Path(__file__).resolve().parents[1]
SMOKE = REPO / "procedures" / "smoke.yaml"
ALIAS_BOMB = textwrap.dedent("""\
    a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]
    b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]
    c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]
    d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]
    e: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]
    f: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]
    g: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]
    h: &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]
    i: &i [*h,*h,*h,*h,*h,*h,*h,*h,*h]
    """)


def run_cli(capsys, *argv: str) -> tuple[int, str]:
    capsys.readouterr()
    code = main(list(argv))
    captured = capsys.readouterr()
    text = captured.out + captured.err
    assert "Traceback" not in text
    return code, text


def smoke_with_station(tmp_path: Path, station: str) -> Path:
    text = SMOKE.read_text().replace("station: ../stations/sim.yaml", f"station: {station}")
    path = tmp_path / "proc.yaml"
    path.write_text(text)
    return path


# -- procedures and stations -----------------------------------------------------------------

@pytest.mark.parametrize("nested", ["flow", "block"])
def test_deep_nesting_is_bad_input_naming_the_line(tmp_path: Path, capsys, nested: str) -> None:
    path = tmp_path / "deep.yaml"
    if nested == "flow":
        path.write_text("version: 1\nname: " + "[" * 5000 + "]" * 5000 + "\n")
    else:
        path.write_text("version: 1\nname:\n" + "".join("  " * i + "- \n" for i in range(1, 300)))
    code, text = run_cli(capsys, "validate", str(path))
    assert code == EXIT_BAD_INPUT
    line = 2 if nested == "flow" else 66     # where the 65th level opens
    assert f"{path}:{line}: malformed YAML: nested deeper than 64 levels" in text


def test_nul_byte_is_bad_input_naming_the_line(tmp_path: Path, capsys) -> None:
    path = tmp_path / "nul.yaml"
    path.write_bytes(b"version: 1\nname: a\x00b\n")
    code, text = run_cli(capsys, "validate", str(path))
    assert code == EXIT_BAD_INPUT
    assert f"{path}:2: cannot read the file: a NUL byte" in text


def test_station_dev_zero_is_refused_without_reading_it(tmp_path: Path, capsys) -> None:
    code, text = run_cli(capsys, "validate", str(smoke_with_station(tmp_path, "/dev/zero")),
                         "--allow-outside-paths")
    assert code == EXIT_BAD_INPUT
    assert "/dev/zero: is a device; expected a regular file" in text


# -- confinement: files named inside a procedure or station -----------------------------------

@pytest.mark.parametrize("target", ["/etc/shadow", "/etc/passwd", "/dev/zero"])
def test_a_station_outside_the_project_is_refused_before_it_is_read(
        tmp_path: Path, capsys, target: str) -> None:
    """Defect 4: `station: /etc/shadow` echoed the file's lines; now it is never opened."""
    path = smoke_with_station(tmp_path, target)
    code, text = run_cli(capsys, "validate", str(path))
    assert code == EXIT_BAD_INPUT
    assert f"{path}:16: station: {target} is outside {tmp_path}" in text
    assert "give --allow-outside-paths to read it" in text
    assert "root:" not in text and "daemon" not in text


def test_allowed_outside_paths_still_never_echo_the_file(tmp_path: Path, capsys) -> None:
    code, text = run_cli(capsys, "validate", str(smoke_with_station(tmp_path, "/etc/passwd")),
                         "--allow-outside-paths")
    assert code == EXIT_BAD_INPUT
    assert "/etc/passwd" in text and "root:" not in text and "/bin/" not in text


def test_run_sim_never_copies_a_file_from_outside_into_the_run_folder(
        tmp_path: Path, capsys) -> None:
    """Defect 4: `run --sim` copied /etc/passwd into the run folder after validate said OK."""
    station = tmp_path / "station.yaml"
    station.write_text((REPO / "stations" / "sim.yaml").read_text().replace(
        "gyro_model: ../gyro-models/nominal-fog.yaml", "gyro_model: /etc/passwd"))
    path = smoke_with_station(tmp_path, str(station))
    out = tmp_path / "run"
    code, text = run_cli(capsys, "run", str(path), "--sim", "--out", str(out))
    assert code == EXIT_BAD_INPUT
    assert f"simulation.gyro_model: /etc/passwd is outside {tmp_path}" in text
    copied = [p for p in out.rglob("*") if p.is_file() and b"root:" in p.read_bytes()] \
        if out.exists() else []
    assert copied == []


def test_files_beside_the_procedure_and_in_its_project_need_no_flag(
        tmp_path: Path, capsys) -> None:
    project = tmp_path / "lab"
    (project / "stations").mkdir(parents=True)
    (project / "procedures").mkdir()
    (project / "stations" / "sim.yaml").write_text((REPO / "stations" / "sim.yaml").read_text()
                                                   .replace("../gyro-models/nominal-fog.yaml",
                                                            "nominal-fog.yaml"))
    (project / "stations" / "nominal-fog.yaml").write_text(
        (REPO / "gyro-models" / "nominal-fog.yaml").read_text())
    path = project / "procedures" / "smoke.yaml"
    path.write_text(SMOKE.read_text())             # station: ../stations/sim.yaml
    code, text = run_cli(capsys, "validate", str(path))
    assert code == 0, text


@pytest.mark.timeout(30)
def test_station_fifo_is_refused_instead_of_hanging(tmp_path: Path, capsys) -> None:
    fifo = tmp_path / "station.fifo"
    os.mkfifo(fifo)
    code, text = run_cli(capsys, "validate", str(smoke_with_station(tmp_path, str(fifo))))
    assert code == EXIT_BAD_INPUT
    assert f"{fifo}: is a FIFO (named pipe); expected a regular file" in text


@pytest.mark.timeout(60)
def test_alias_bomb_procedure_is_refused_in_bounded_memory(tmp_path: Path, capsys) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(ALIAS_BOMB)
    code, text = run_cli(capsys, "validate", str(path))
    assert code == EXIT_BAD_INPUT
    assert "expands to more than 200000 values (alias bomb?)" in text


# -- model files -----------------------------------------------------------------------------

MODEL_CASES = {
    "alias bomb": (ALIAS_BOMB, "alias bomb"),
    "duplicate key": ("version: 1\nscale_factor: 1.0\nscale_factor: 2.0\n",
                      "x.yaml:3: scale_factor: duplicate key (first given on line 2)"),
    "deep nesting": ("version: 1\nscale_factor: " + "[" * 3000 + "]" * 3000 + "\n",
                     "x.yaml:2: malformed YAML: nested deeper than 64 levels"),
    "NUL byte": ("version: 1\nscale_factor: 1\x00\n", "x.yaml:2: cannot read the file: a NUL byte"),
    "python tag": ("version: 1\nscale_factor: !!python/object:os.system 1\n",
                   "x.yaml:2: scale_factor: unsupported YAML tag"),
    "not a mapping": ("[1, 2, 3]\n", "x.yaml"),
    "bad effect list": ("version: 1\nscale_factor: 1\neffects: {a: 1}\n", "effects"),
}


@pytest.mark.timeout(60)
@pytest.mark.parametrize("case", sorted(MODEL_CASES))
def test_bad_model_files_are_bad_input(tmp_path: Path, capsys, case: str) -> None:
    text, expected = MODEL_CASES[case]
    model = tmp_path / "x.yaml"
    model.write_text(text)
    code, out = run_cli(capsys, "discrepancy", "--model", str(model), "--measured",
                        str(tmp_path / "nowhere"), "--out", str(tmp_path / "d"))
    assert code == EXIT_BAD_INPUT
    assert expected in out


@pytest.mark.timeout(300)
def test_valid_model_without_noise_block_is_bad_input_not_a_linalg_traceback(
        smoke_run: Path, tmp_path: Path, capsys) -> None:
    model = tmp_path / "no-noise.yaml"
    model.write_text("version: 1\nscale_factor: 1.0\n")
    code, out = run_cli(capsys, "discrepancy", "--model", str(model), "--measured",
                        str(smoke_run), "--out", str(tmp_path / "d"))
    assert code == EXIT_BAD_INPUT
    assert "the model has no noise terms" in out


# -- logs and run folders --------------------------------------------------------------------

def test_binary_garbage_to_analyze_allan_is_bad_input_and_not_echoed(tmp_path: Path, capsys) -> None:
    garbage = tmp_path / "log.csv"
    payload = bytes(range(256)) * 40 + b"SECRET-CONTENT"
    garbage.write_bytes(payload)
    code, out = run_cli(capsys, "analyze", "allan", str(garbage))
    assert code == EXIT_BAD_INPUT
    assert f"{garbage}:1: cannot read the file: a NUL byte" in out
    assert "SECRET" not in out and "\x01" not in out


def test_binary_non_utf8_csv_is_refused_naming_the_line(tmp_path: Path, capsys) -> None:
    log = tmp_path / "log.csv"
    log.write_bytes(b"t_s,gyro\n0,1\n\xff\xfe\xfd garbage\n")
    code, out = run_cli(capsys, "analyze", "allan", str(log))
    assert code == EXIT_BAD_INPUT
    assert f"{log}:3: cannot read the file: not UTF-8 text" in out


def test_malformed_journal_line_fails_verify_with_its_line_number(
        smoke_run: Path, tmp_path: Path, capsys) -> None:
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(smoke_run, copy)
    journal = copy / "journal.jsonl"
    lines = journal.read_bytes().splitlines(keepends=True)
    lines[3] = b"{not json at all\n"
    journal.write_bytes(b"".join(lines))
    code, out = run_cli(capsys, "verify", str(copy))
    assert code == EXIT_ACCEPTANCE_FAILED
    assert "journal.jsonl:4:" in out


# -- signals and disk --------------------------------------------------------------------------

@pytest.mark.timeout(60)
def test_sigterm_before_the_engine_handlers_exits_3_without_traceback(tmp_path: Path) -> None:
    """SIGTERM while the procedure is still being loaded (old main: killed by signal, -15)."""
    script = textwrap.dedent(f"""
        import os, signal, sys
        from gyrocal import cli
        from gyrocal.app import run_commands as commands
        original = commands.load_procedure
        def load_procedure(*args, **kwargs):
            os.kill(os.getpid(), signal.SIGTERM)
            return original(*args, **kwargs)
        commands.load_procedure = load_procedure
        sys.exit(cli.main(["run", {str(SMOKE)!r}, "--sim", "--out", {str(tmp_path / 'r')!r}]))
        """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == EXIT_FAULT, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "interrupted" in proc.stderr
    assert not (tmp_path / "r").exists()       # nothing was created, nothing moved


# -- property: no generated input gives a traceback --------------------------------------------

_scalar = st.one_of(st.none(), st.booleans(), st.integers(-10**12, 10**12),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12))
_yaml_text = st.recursive(
    _scalar.map(lambda v: repr(v) if not isinstance(v, str) else v),
    lambda children: st.one_of(
        st.lists(children, max_size=4).map(lambda xs: "[" + ", ".join(xs) + "]"),
        st.dictionaries(st.sampled_from(["version", "name", "station", "sequence", "noise",
                                         "scale_factor", "effects", "chamber", "table", "gyro",
                                         "defaults", "tests", "setpoint_c", "&a x", "<<"]),
                        children, max_size=4)
        .map(lambda d: "{" + ", ".join(f"{k}: {v}" for k, v in d.items()) + "}"),
    ),
    max_leaves=12,
)
_documents = st.one_of(
    _yaml_text,
    st.binary(max_size=200).map(lambda b: b.decode("latin-1")),
    st.text(max_size=200),
    st.sampled_from([SMOKE.read_text(), (REPO / "stations" / "sim.yaml").read_text(),
                     (REPO / "gyro-models" / "nominal-fog.yaml").read_text()])
    .flatmap(lambda t: st.integers(0, len(t)).flatmap(
        lambda i: st.text(max_size=8).map(lambda s: t[:i] + s + t[i:]))),
)


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(doc=_documents, kind=st.sampled_from(["procedure", "station", "model", "log"]))
def test_no_generated_input_gives_a_traceback_or_a_strange_exit(
        tmp_path_factory, capsys, doc: str, kind: str) -> None:
    folder = tmp_path_factory.mktemp("fuzz")
    path = folder / ("x.csv" if kind == "log" else "x.yaml")
    path.write_bytes(doc.encode("utf-8", "surrogateescape"))
    argv = {
        "procedure": ["validate", str(path)],
        "station": ["validate", str(SMOKE), "--station", str(path)],
        "model": ["discrepancy", "--model", str(path), "--measured", str(folder / "none"),
                  "--out", str(folder / "d")],
        "log": ["analyze", "allan", str(path)],
    }[kind]
    code, text = run_cli(capsys, *argv)
    assert code in (EXIT_OK, EXIT_ACCEPTANCE_FAILED, EXIT_BAD_INPUT, EXIT_FAULT)
    assert "internal error" not in text, text
