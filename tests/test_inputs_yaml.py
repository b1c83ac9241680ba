"""YAML loading with line numbers: paths, duplicate keys, malformed YAML, includes."""

import os
import textwrap

import pytest

from gyrocal.inputs import InputError as ProcedureError
from gyrocal.inputs import load_yaml

pytestmark = pytest.mark.timeout(30)


def write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


def line_of(path, fragment):
    """1-based line of the first line containing ``fragment`` (independent of the loader)."""
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if fragment in line:
            return number
    raise AssertionError(f"{fragment!r} not in {path}")


def problems_of(path):
    with pytest.raises(ProcedureError) as error:
        load_yaml(path)
    return [str(p) for p in error.value.problems]


def test_every_key_path_knows_its_line(tmp_path):
    path = write(tmp_path / "p.yaml", """
        name: x
        sequence:
          - setpoint_c: 20
            tests:
              - kind: sf_sweep
                rates_dps:
                  - 10
                  - 650
          - setpoint_c: 30
        """)
    doc = load_yaml(path)
    assert doc.data["sequence"][0]["tests"][0]["rates_dps"] == [10, 650]
    assert doc.where(("sequence", 0, "tests", 0, "rates_dps", 1)).line == line_of(path, "- 650")
    assert doc.where(("sequence", 1, "setpoint_c")).line == line_of(path, "setpoint_c: 30")
    # a key that is not there is placed at its nearest ancestor
    assert doc.where(("sequence", 1, "tests")).line == line_of(path, "setpoint_c: 30")
    problem = doc.problem(("sequence", 0, "tests", 0, "rates_dps", 1), "too fast")
    assert str(problem) == f"{path}:{line_of(path, '- 650')}: sequence[0].tests[0].rates_dps[1]: too fast"


def test_duplicate_keys_are_errors_with_both_lines(tmp_path):
    path = write(tmp_path / "dup.yaml", """
        name: a
        defaults:
          dwell: 3 min
          settle: 20 s
          dwell: 5 min
        """)
    first, second = line_of(path, "dwell: 3 min"), line_of(path, "dwell: 5 min")
    assert problems_of(path) == [
        f"{path}:{second}: defaults.dwell: duplicate key (first given on line {first})"
    ]


def test_merge_keys_may_override_without_being_duplicates(tmp_path):
    path = write(tmp_path / "merge.yaml", """
        base: &base {dwell: 3 min, settle: 20 s}
        test:
          <<: *base
          dwell: 5 min
        """)
    assert load_yaml(path).data["test"] == {"dwell": "5 min", "settle": "20 s"}


def test_malformed_yaml_reports_the_line_of_the_yaml_error(tmp_path):
    path = write(tmp_path / "bad.yaml", """
        name: a
        sequence:
          - setpoint_c: 20
           tests: [1, 2
        """)
    [problem] = problems_of(path)
    assert problem.startswith(f"{path}:{line_of(path, 'tests: [1, 2')}: malformed YAML: ")


def test_unclosed_flow_list_points_at_where_yaml_gave_up(tmp_path):
    path = write(tmp_path / "bad2.yaml", "a: [1, 2\nb: 3\n")
    [problem] = problems_of(path)
    assert problem.startswith(f"{path}:2: malformed YAML: ")


def test_tabs_and_unsupported_tags_are_reported(tmp_path):
    path = write(tmp_path / "tag.yaml", "a: !!python/object:os.system {}\nb: !custom 3\n")
    assert problems_of(path) == [
        f"{path}:1: a: unsupported YAML tag tag:yaml.org,2002:python/object:os.system",
        f"{path}:2: b: unsupported YAML tag !custom",
    ]


def test_bad_date_is_a_problem_not_a_crash(tmp_path):
    path = write(tmp_path / "date.yaml", "due: 2027-13-45\n")
    [problem] = problems_of(path)
    assert problem.startswith(f"{path}:1: due: cannot read '2027-13-45'")


def test_missing_file_and_non_utf8_file(tmp_path):
    assert problems_of(tmp_path / "nope.yaml") == [f"{tmp_path / 'nope.yaml'}: file not found"]
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"name: \xff\xfe\n")
    [problem] = problems_of(binary)
    assert problem.startswith(f"{binary}:1: cannot read the file: not UTF-8 text")


def test_recursive_alias_and_alias_bomb_do_not_hang(tmp_path):
    path = write(tmp_path / "rec.yaml", "a: &a [1, *a]\n")
    assert problems_of(path) == [f"{path}:1: a[1]: recursive alias"]
    bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
    for level in "bcdefgh":
        prev = chr(ord(level) - 1)
        bomb += f"{level}: &{level} [*{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}]\n"
    path = write(tmp_path / "bomb.yaml", bomb)
    [problem] = problems_of(path)
    assert "expands to more than" in problem


def test_include_splices_a_file_and_reports_lines_inside_it(tmp_path):
    write(tmp_path / "proc" / "parts" / "sweep.yaml", """
        kind: sf_sweep
        rates_dps: [10, 20]
        """)
    path = write(tmp_path / "proc" / "main.yaml", """
        name: with include
        tests:
          - !include parts/sweep.yaml
        """)
    doc = load_yaml(path)
    assert doc.data["tests"][0] == {"kind": "sf_sweep", "rates_dps": [10, 20]}
    where = doc.where(("tests", 0, "rates_dps", 1))
    assert (where.file, where.line) == (os.path.join(str(tmp_path / "proc"), "parts", "sweep.yaml"), 2)
    assert len(doc.files) == 2


def test_include_may_not_leave_the_procedure_folder(tmp_path):
    write(tmp_path / "outside.yaml", "secret: 1\n")
    path = write(tmp_path / "proc" / "main.yaml", "name: x\npart: !include ../outside.yaml\n")
    [problem] = problems_of(path)
    assert problem.startswith(f"{path}:2: part: !include ../outside.yaml leaves the folder ")
    assert "includes must stay inside it" in problem


def test_include_through_a_symlink_that_points_outside_is_refused(tmp_path):
    write(tmp_path / "outside" / "part.yaml", "secret: 1\n")
    (tmp_path / "proc").mkdir()
    os.symlink(tmp_path / "outside", tmp_path / "proc" / "link")
    path = write(tmp_path / "proc" / "main.yaml", "part: !include link/part.yaml\n")
    [problem] = problems_of(path)
    assert "leaves the folder" in problem and str(tmp_path / "outside" / "part.yaml") in problem


def test_include_cycle_is_reported(tmp_path):
    write(tmp_path / "a.yaml", "b: !include b.yaml\n")
    write(tmp_path / "b.yaml", "a: !include a.yaml\n")
    [problem] = problems_of(tmp_path / "a.yaml")
    assert problem == f"{tmp_path / 'b.yaml'}:1: b.a: !include a.yaml includes itself"
