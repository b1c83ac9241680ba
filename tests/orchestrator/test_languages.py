"""The reference and the JSON Schemas say what the parsers accept, and stay that way.

* The committed ``docs/reference/`` and ``docs/schemas/`` equal what
  ``docs/generate.py`` writes today.
* For every mapping of every shipped procedure, station and model file (and the
  examples in the reference), an unknown key injected there is refused by the real
  parser, and the keys the parser says are allowed there are the keys the description
  lists: the description cannot drift from ``gyrocal validate``.
* Every shipped YAML validates against its JSON Schema, and the same injected key,
  a bare number for a duration and a wrong unit are each rejected by the schema.
* ``gyrocal validate`` links each problem to the section that explains its key.
"""

from __future__ import annotations

import copy
import datetime as dt
import re
import shutil
from pathlib import Path

import jsonschema
import pytest
import yaml

from gyrocal.app import reference_docs
from gyrocal.cli import main
from gyrocal.inputs import format_key_path, load_yaml
from gyrocal.models.gyro_model import ModelError
from gyrocal.models.imu_model import load_any_model
from gyrocal.orchestrator.languages import (
    LANGUAGES,
    MODEL,
    PROCEDURE,
    STATION,
    Either,
    Language,
    ListOf,
    Section,
    Shape,
    Variants,
    choose,
)
from gyrocal.orchestrator.procedure import load_procedure
from gyrocal.orchestrator.station import load_station
from gyrocal.problems import ProcedureError

REPO = Path(__file__).resolve().parents[2]
FOLDERS = {PROCEDURE.name: "procedures", STATION.name: "stations", MODEL.name: "gyro-models"}
INJECTED = "zz_not_a_key"


def shipped(language: Language) -> list[Path]:
    return sorted((REPO / FOLDERS[language.name]).glob("*.yaml"))


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the shipped project folders, where edited files are written and parsed."""
    root = tmp_path_factory.mktemp("project")
    for folder in FOLDERS.values():
        shutil.copytree(REPO / folder, root / folder)
    (root / "procedures" / "reference-example.yaml").write_text(reference_docs.PROCEDURE_EXAMPLE)
    (root / "gyro-models" / "reference-example.yaml").write_text(reference_docs.MODEL_EXAMPLE)
    # no shipped station notifies anyone; this one does, so notify[] is checked too
    (root / "stations" / "with-notify.yaml").write_text(
        (REPO / "stations" / "sim.yaml").read_text() + "notify:\n"
        "  - {url: \"json://127.0.0.1:9/hook\", on: [finished, faulted]}\n"
        "  - {command: [\"true\"]}\n")
    return root


def as_json(value: object) -> object:
    """YAML data as a JSON document (dates as ISO text, as an editor sees them)."""
    if isinstance(value, dict):
        return {k: as_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [as_json(v) for v in value]
    if isinstance(value, dt.date):
        return value.isoformat()
    return value


def mappings(shape: Shape, data: object, path: tuple = ()) -> list[tuple[tuple, Section]]:
    """Every mapping of ``data`` with the section that describes it."""
    shape = choose(shape, data)
    found: list[tuple[tuple, Section]] = []
    if isinstance(shape, ListOf) and isinstance(data, list):
        for index, item in enumerate(data):
            found += mappings(shape.item, item, (*path, index))
    elif isinstance(shape, Section) and isinstance(data, dict) and shape.open_keys is None:
        found.append((path, shape))
        for key in shape.keys:
            if key.name in data:
                found += mappings(key.value, data[key.name], (*path, key.name))
    elif isinstance(shape, (Variants, Either)):
        raise AssertionError(f"unresolved {shape} at {path}")
    return found


def inject(data: object, path: tuple) -> object:
    edited = copy.deepcopy(data)
    target = edited
    for part in path:
        target = target[part]
    target[INJECTED] = 1
    return edited


def parser_allowed_keys(language: Language, file: Path, path: tuple) -> set[str]:
    """What the real parser says is allowed where the unknown key was injected."""
    where = format_key_path((*path, INJECTED))
    try:
        if language is MODEL:
            load_any_model(file)
        elif language is STATION:
            load_station(file)
        else:
            load_procedure(file)
    except ModelError as error:
        lines = [line for line in str(error).splitlines() if f": {where}: " in line]
        assert lines, str(error)
        message = lines[0]
        # unknown keys as the common schema reader lists them, matrix elements and axes
        # as the model reader does
        listed = (re.search(r"(?:elements are|axes are):? ([\w, ]+)", message)
                  or re.search(r"\((?:allowed here: )?([\w, ]+)\)$", message))
    except ProcedureError as error:
        messages = [p.message for p in error.problems if p.path == where]
        assert messages, f"{where} not reported: {error}"
        message = messages[0]
        listed = re.search(r"\((?:allowed here: )?([\w, ]+)\)$", message)
    else:
        raise AssertionError(f"{file}: the parser accepted {where}")
    assert listed, message
    return {k.strip() for k in listed.group(1).split(",")}


def _cases() -> list[tuple[Language, str]]:
    cases = [(lang, path.name) for lang in LANGUAGES for path in shipped(lang)]
    return [*cases, (PROCEDURE, "reference-example.yaml"), (MODEL, "reference-example.yaml"),
            (STATION, "with-notify.yaml")]


@pytest.mark.parametrize(("language", "name"), _cases(), ids=lambda c: getattr(c, "name", c))
def test_the_described_keys_are_the_keys_the_parser_allows(
        project: Path, language: Language, name: str) -> None:
    file = project / FOLDERS[language.name] / name
    original = file.read_text()
    data = load_yaml(file).data
    cases = mappings(language.root, data)
    assert cases, name
    try:
        for path, section in cases:
            file.write_text(yaml.safe_dump(inject(data, path), sort_keys=False, allow_unicode=True))
            described = {k.name for k in section.keys}
            if section.anchor == "model-v2-axis":
                # an axis is parsed as a version-1 model: the parser lists the two keys that
                # an axis may not have (version is supplied, earth_rate_dph refused by name)
                described |= {"version", "earth_rate_dph"}
            allowed = parser_allowed_keys(language, file, path)
            assert allowed == described, (name, format_key_path(path), section.anchor)
    finally:
        file.write_text(original)


@pytest.mark.parametrize("language", LANGUAGES, ids=lambda lang: lang.name)
def test_every_section_is_held_against_its_parser(project: Path, language: Language) -> None:
    """Every section of the description was met in some shipped file or example above (the
    effects come from the catalogue table itself; one of them is enough)."""
    met: set[str] = set()
    for name in [n for lang, n in _cases() if lang is language]:
        file = project / FOLDERS[language.name] / name
        met |= {section.anchor for _, section in mappings(language.root, load_yaml(file).data)}
    described = {s.anchor for _, s in mappings_of_description(language.root)}
    if language is PROCEDURE:   # an inline station is the station language, checked there
        described -= {s.anchor for _, s in mappings_of_description(STATION.root)}
    unmet = {a for a in described - met if not a.startswith("effect-")}
    assert not unmet
    assert language is not MODEL or any(a.startswith("effect-") for a in met)


def mappings_of_description(shape: Shape, seen: set[int] | None = None) -> list[tuple[str, Section]]:
    seen = set() if seen is None else seen
    if id(shape) in seen:
        return []
    seen.add(id(shape))
    if isinstance(shape, Section):
        own = [] if shape.open_keys is not None else [(shape.anchor, shape)]
        return own + [m for k in shape.keys for m in mappings_of_description(k.value, seen)]
    if isinstance(shape, ListOf):
        return mappings_of_description(shape.item, seen)
    if isinstance(shape, Either):
        return [m for o in shape.options for m in mappings_of_description(o, seen)]
    if isinstance(shape, Variants):
        return [m for _, s in shape.sections for m in mappings_of_description(s, seen)]
    return []


# -- JSON Schemas -------------------------------------------------------------------------

def validator(language: Language) -> jsonschema.Draft7Validator:
    schema = reference_docs.json_schema(language)
    jsonschema.Draft7Validator.check_schema(schema)
    return jsonschema.Draft7Validator(schema)


@pytest.mark.parametrize(("language", "name"), _cases(), ids=lambda c: getattr(c, "name", c))
def test_every_shipped_yaml_validates_and_a_mistyped_key_anywhere_is_rejected(
        project: Path, language: Language, name: str) -> None:
    check = validator(language)
    data = as_json(load_yaml(project / FOLDERS[language.name] / name).data)
    errors = [e.message for e in check.iter_errors(data)]
    assert errors == [], name
    for path, _ in mappings(language.root, data):
        assert not check.is_valid(inject(data, path)), (name, format_key_path(path))


def test_the_schema_rejects_what_validate_rejects_in_values(project: Path) -> None:
    check = validator(PROCEDURE)
    data = as_json(load_yaml(project / "procedures" / "smoke.yaml").data)
    assert check.is_valid(data)
    for path, value, why in (
        (("defaults", "dwell"), 10, "a duration needs its unit"),
        (("defaults", "dwell"), "10 parsecs", "unknown time unit"),
        (("sequence", 0, "setpoint_c"), "25 deg/s", "a rate is not a temperature"),
        (("sequence", 0, "tests", 0, "kind"), "statik", "unknown test kind"),
        (("acceptance", 0, "metric"), "nonlinearity.rms", "unknown metric"),
        (("data_quality", "max_lost_frame_fraction"), 0.9, "above its maximum"),
    ):
        edited = copy.deepcopy(data)
        target = edited
        for part in path[:-1]:
            target = target[part]
        target[path[-1]] = value
        assert not check.is_valid(edited), why
    sweep = copy.deepcopy(data)
    sweep["sequence"][0]["tests"][1]["dwel"] = "3 s"
    messages = [e.message for e in check.iter_errors(sweep)]
    assert any("'dwel' was unexpected" in m for m in messages), messages
    # and the units the parser takes are taken
    units = copy.deepcopy(data)
    units["sequence"][0]["setpoint_c"] = "296.15 K"
    units["defaults"]["dwell"] = "1 h 30 min"
    units["defaults"]["accel_dps2"] = "1 rad/s^2"
    assert check.is_valid(units)


# -- the committed files ------------------------------------------------------------------

def test_the_committed_reference_is_what_the_generator_writes() -> None:
    for relative, text in reference_docs.documents().items():
        committed = REPO / relative
        assert committed.is_file(), f"{relative} missing: run .venv/bin/python docs/generate.py"
        assert committed.read_text(encoding="utf-8") == text, \
            f"{relative} differs from the generator: run .venv/bin/python docs/generate.py"


def test_the_reference_links_resolve() -> None:
    """Every relative link and #anchor in docs/reference/ and the README points somewhere."""
    files = [*sorted((REPO / "docs" / "reference").glob("*.md")), REPO / "README.md",
             REPO / "docs" / "tutorial.md"]
    for file in files:
        text = file.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if "://" in target:
                continue
            relative, _, anchor = target.partition("#")
            linked = (file.parent / relative).resolve() if relative else file
            assert linked.exists(), (file.name, target)
            if anchor and linked.suffix == ".md":
                assert f'id="{anchor}"' in linked.read_text(encoding="utf-8"), (file.name, target)
        assert "../shared" not in text, file.name


# -- validate points at the reference -----------------------------------------------------

def test_validate_links_each_problem_to_the_section_that_explains_it(
        project: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    smoke = (project / "procedures" / "smoke.yaml").read_text()
    edited = smoke.replace("{kind: sf_sweep, rates_dps: [10, 50, 100]}",
                           "{kind: sf_sweep, rates_dps: [10, 50, 100], dwel: 3 s}", 1)
    edited = edited.replace("max_step_repeats: 2", "max_step_repeat: 2")
    assert edited.count("dwel:") == 1
    file = project / "procedures" / "typo.yaml"
    file.write_text(edited)
    monkeypatch.chdir(project)
    assert main(["validate", "procedures/typo.yaml"]) == 2
    err = capsys.readouterr().err
    assert re.search(r"procedures/typo\.yaml:\d+: sequence\[0\]\.tests\[1\]\.dwel: unknown key "
                     r".*\(see docs/reference/procedure\.md#test-sf_sweep\)", err), err
    assert "data_quality.max_step_repeat: unknown key" in err
    assert "(see docs/reference/procedure.md#data_quality)" in err
    assert "Traceback" not in err
    for anchor in ("test-sf_sweep", "data_quality"):
        assert f'id="{anchor}"' in (REPO / PROCEDURE.doc_file).read_text(encoding="utf-8")


def test_a_station_problem_links_the_station_reference(
        project: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    station = (project / "stations" / "sim.yaml").read_text()
    (project / "stations" / "typo.yaml").write_text(
        station.replace("baudrate: 921600", "baudrate: 921600\n  sample_rate: 2000"))
    smoke = (project / "procedures" / "smoke.yaml").read_text()
    (project / "procedures" / "typo-station.yaml").write_text(
        smoke.replace("../stations/sim.yaml", "../stations/typo.yaml"))
    monkeypatch.chdir(project)
    assert main(["validate", "procedures/typo-station.yaml"]) == 2
    err = capsys.readouterr().err
    assert re.search(r"stations/typo\.yaml:\d+: gyro\.sample_rate: unknown key .*"
                     r"\(see docs/reference/station\.md#gyro\)", err), err
