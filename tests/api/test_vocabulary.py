"""Every table the API returns speaks one vocabulary (``labrig.vocabulary``)."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from support.api_runs import cli

import labrig
from labrig.vocabulary import ALIASES, PATTERNS, VOCABULARY, known

REPO = Path(__file__).resolve().parents[2]
RAW_LOGS = ("pressure", "pump", "length")


@pytest.fixture(scope="module")
def tables(quick_run, gent_scan):
    """(table name, alias group or None, DataFrame) for every table of the demo run, a
    campaign of it, the model's path of its pair and a small scan."""
    run = labrig.open_run(quick_run)
    path = labrig.actuator(*run.protocol.specimen.segments, fittings_length_mm=10).path(
        deflate=True
    )
    scan = labrig.open_scan(gent_scan)
    return [
        *((f"Run.raw_table({log})", None, run.raw_table(1, log)) for log in RAW_LOGS),
        ("Run.curves_table", "curves", run.curves_table("inflate")),
        ("Run.transitions", "transitions", run.transitions),
        ("Run.agreed_transitions", None, run.agreed_transitions),
        ("Run.comparison", "comparison", run.comparison),
        ("Run.paper_comparison", "comparison", run.paper_comparison),
        ("Run.model_path", None, run.model_path),
        ("Run.repetitions", None, run.repetitions),
        ("open_runs", None, labrig.open_runs(quick_run)),
        ("open_runs(long=True)", None, labrig.open_runs(quick_run, long=True)),
        ("Segment.curve", "model curve", labrig.segment("B46-T20").curve),
        ("ActuatorPath.path", "model path", path.path),
        ("ActuatorPath.transitions", None, path.transitions),
        ("ActuatorPath.paper_transitions", None, path.paper_transitions),
        ("Scan.transitions", None, scan.transitions),
        ("Scan.paper_transitions", "scan", scan.paper_transitions),
    ]


def test_every_column_is_the_vocabularys_or_a_json_name_beside_its_own(tables):
    for name, group, table in tables:
        aliases = ALIASES.get(group, {})
        for column in table.columns:
            if column in aliases:  # the JSON's name: its vocabulary name is right after
                after = table.columns[table.columns.get_loc(column) + 1]
                assert after == aliases[column], (name, column)
                assert table[after].equals(table[column]), (name, column)
            else:
                assert known(column), f"{name}: {column!r} is not in the vocabulary"


def test_each_quantity_has_one_name(tables):
    """The direction is named, everywhere; the same path's volume, pressure and length
    (with the fittings) are the same columns in the run's and the model's tables."""
    by_name = {name: table for name, _, table in tables}
    for name, table in by_name.items():
        if "direction" in table:
            assert set(table["direction"]) <= {"inflate", "deflate"}, name
        if "direction_sign" in table:
            signs = np.where(table["direction"] == "inflate", 1, -1)
            np.testing.assert_array_equal(table["direction_sign"], signs, name)
    assert set(by_name["ActuatorPath.transitions"]["direction"]) == {"inflate", "deflate"}
    run_path, model_path = by_name["Run.model_path"], by_name["ActuatorPath.path"]
    for column in ("volume_ml", "pressure_kpa", "length_mm", "direction"):
        assert column in run_path and column in model_path
    # the demo's specimen has 10 mm of fittings: one length at the start of both paths
    assert run_path["length_mm"].iloc[0] == pytest.approx(model_path["length_mm"].iloc[0])
    assert model_path["length_mm"].iloc[0] == pytest.approx(model_path["l_mm"].iloc[0] + 10)
    # the comparison's phase is its direction
    comparison = by_name["Run.comparison"]
    assert list(comparison["direction"]) == list(comparison["phase"])


def _json_tables(document: dict, where: dict[str, str | None]) -> list:
    """(label, alias group, field names in order) of each table in a command's JSON:
    ``where`` maps a key of ``document`` to its alias group; "" stands for the document
    itself (the fields of one object), a list value is a table of rows."""
    found = []
    for key, group in where.items():
        value = document if key == "" else document[key]
        rows = value if isinstance(value, list) else [value]
        assert rows, f"{key}: an empty table checks nothing"
        found += [(key, group, list(row)) for row in rows]
    return found


def test_every_field_of_the_commands_json_is_the_vocabularys_or_beside_its_own(quick_run, capsys):
    """The command line's JSON speaks the vocabulary too: each quantity under a
    vocabulary name, or under the name its scripts rely on with the vocabulary's right
    after it."""
    documents = {
        ("compare", quick_run, "--json"): {
            "transitions": "comparison",
            "paper_transitions": "comparison",
            "unpredicted": "comparison",
        },
        ("model", "path", "B46-T20", "B46-T22", "--json"): {
            "path": "model path",
            "transitions": None,
            "paper_transitions": None,
        },
        ("runs", quick_run, "--json"): {"runs": None},
    }
    checked = 0
    for argv, where in documents.items():
        code, out, err = cli(list(argv), capsys)
        assert code == 0, err
        for key, group, names in _json_tables(json.loads(out), where):
            aliases = ALIASES.get(group, {})
            for k, name in enumerate(names):
                if name in aliases:
                    assert names[k + 1] == aliases[name], (argv, key, name)
                else:
                    assert known(name), f"{' '.join(argv[:2])} {key}: {name!r}"
                checked += 1
    code, out, err = cli(["model", "curve", "B46-T20", "--json"], capsys)
    assert code == 0, err
    curve = json.loads(out)
    names = [n for n in curve if isinstance(curve[n], list)]  # the table's columns
    assert names == ["v_ml", "volume_ml", "p_kpa", "pressure_kpa", "l_mm", "segments_length_mm"]
    assert curve["volume_ml"] == curve["v_ml"] and curve["pressure_kpa"] == curve["p_kpa"]
    assert checked > 50


def test_the_reference_states_the_vocabulary_as_the_code_does():
    text = (REPO / "docs/reference/python-api.md").read_text(encoding="utf-8")
    for name, meaning in VOCABULARY.items():
        assert f"| `{name}` | {meaning} |" in text, name
    for group, aliases in ALIASES.items():
        row = next(line for line in text.splitlines() if line.startswith(f"| {group} |"))
        for old, new in aliases.items():
            assert f"`{old}` → `{new}`" in row, (group, old)


def test_the_vocabulary_check_can_fail():
    assert not known("p_meas_kpa") and not known("snap1_pressure")
    assert all(re.compile(p) for p in PATTERNS)
    assert known("snap2_dp_model_kpa") and known("v3_ml") and known("segment2")
