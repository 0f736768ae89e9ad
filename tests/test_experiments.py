"""The experiment framework: the ladder, the registry, the record's provenance, the table and
figure writers (mdroll.experiments)."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import pytest

from mdroll.errors import ParameterError
from mdroll import __version__
from mdroll.experiments import (SIZES, Figure, Ladder, RecordKind, Registry, markdown_table, provenance,
                                read_record, text_table, write_figure, write_figures, write_json)
from mdroll.experiments.record import (FLAGS, INTEGER, NUMBER, NUMBERS, OPTIONAL_NUMBER, OPTIONAL_TEXT, TEXT,
                                       OrAbsent, Rows, Table)


def test_ladder_keeps_the_rungs_in_order_and_names_the_sizes_it_lacks():
    ladder = Ladder(full=3, quick=2)
    assert SIZES == ("test", "quick", "full") and list(ladder) == ["quick", "full"]
    assert ladder.rung("quick") == 2
    with pytest.raises(ParameterError, match="size = 'test' is not allowed: choose one of 'quick', 'full'"):
        ladder.rung("test")
    with pytest.raises(ValueError, match="not on the ladder"):
        Ladder(huge=1)


def test_registry_names_its_entries_once():
    registry = Registry("study", [("a", 1), ("b", 2)])
    assert list(registry) == ["a", "b"] and registry.named("b") == 2
    assert registry.unknown(["c", "a", "d"]) == ["c", "d"]
    with pytest.raises(ParameterError, match="study = 'c' is not allowed: choose one of a, b"):
        registry.named("c")
    with pytest.raises(ValueError, match="registered twice"):
        registry.add("a", 3)


def test_provenance_and_the_record_file(tmp_path):
    from mdroll import Params

    record = provenance("cpu", "quick", 7, {"base": Params(L=0.1), "lengths": (1.0, 2.0)})
    assert (record["size"], record["seed"]) == ("quick", 7)
    assert record["parameters"]["base"]["L"] == 0.1 and record["parameters"]["lengths"] == [1.0, 2.0]
    env = record["environment"]
    assert env["mdroll"] == __version__ and env["device"] == "cpu" and env["device_name"] and env["date"]
    assert "git_commit" in record
    both = provenance("cpu", devices=["cpu"])
    assert both["environment"]["cpu"]["device"] == "cpu"
    path = write_json(tmp_path / "r.json", {**record, "nan": float("nan")})
    assert json.loads(path.read_text())["nan"] is None


def test_tables():
    text = text_table(("name", "value"), [("a", "1.5"), ("long name", "22")], align="lr")
    assert text.splitlines() == ["name       value", "-" * 16, "a" + " " * 12 + "1.5", "long name" + " " * 5 + "22"]
    assert markdown_table(("x", "y"), [(1, 2)]) == ["| x | y |", "|---|---|", "| 1 | 2 |"]


def test_figures_are_written_as_png(tmp_path):
    figure = Figure("line", "a line", lambda fig: fig.subplots().plot([0, 1], [1, 0]), size=(2, 2))
    assert write_figures([figure], tmp_path) == [tmp_path / "line.png"]
    assert (tmp_path / "line.png").read_bytes()[:4] == b"\x89PNG"
    buffer = io.BytesIO()
    assert write_figure(figure, buffer) is None and buffer.getvalue()[:4] == b"\x89PNG"


KIND = RecordKind("trial record", "mdroll trial", {
    "size": TEXT, "seconds": NUMBER, "rows": Rows({"passes": INTEGER, "error": NUMBERS, "covered": FLAGS}),
    "spec": Table({"mode": TEXT, "seed": OrAbsent(INTEGER)}), "note": OrAbsent(OPTIONAL_TEXT),
    "expected": OPTIONAL_NUMBER})
GOOD = {"size": "quick", "seconds": 1.5, "rows": [{"passes": 2, "error": {"H": -0.01}, "covered": {"H": True}}],
        "spec": {"mode": "coupled"}, "expected": None, "extra": "unchecked"}
READER_CASES = [
    ("another schema", json.dumps({"study": "x"}), "the record lacks 'size' (a text): not a trial record as mdroll "
     "trial writes it"),
    ("truncated", json.dumps(GOOD)[:40], "not a JSON trial record (truncated, or another format)"),
    ("not UTF-8", b"\xff\xfe{}", "not a JSON trial record"),
    ("a JSON list", "[1, 2]", "not a trial record (a JSON list, where mdroll trial writes a table)"),
    ("seconds a text", json.dumps({**GOOD, "seconds": "1.5"}), "seconds = '1.5', expected a number"),
    ("seconds infinite", json.dumps({**GOOD, "seconds": math.inf}), "seconds = 'inf', expected a number"),
    ("rows a table", json.dumps({**GOOD, "rows": {}}), "rows = '{}', expected a list of tables"),
    ("a row a number", json.dumps({**GOOD, "rows": [3]}), "rows[0] = '3', expected a table"),
    ("a row lacks a field", json.dumps({**GOOD, "rows": [{"passes": 1, "error": {}}]}),
     "rows[0] lacks 'covered' (a table of true/false): not a trial record"),
    ("passes a bool", json.dumps({**GOOD, "rows": [{**GOOD["rows"][0], "passes": True}]}),
     "rows[0].passes = 'True', expected an integer"),
    ("an error a text", json.dumps({**GOOD, "rows": [{**GOOD["rows"][0], "error": {"H": "x"}}]}),
     "rows[0].error = \"{'H': 'x'}\", expected a table of numbers"),
    ("spec a list", json.dumps({**GOOD, "spec": []}), "spec = '[]', expected a table"),
    ("spec lacks mode", json.dumps({**GOOD, "spec": {}}), "spec lacks 'mode' (a text)"),
    ("seed present and a text", json.dumps({**GOOD, "spec": {"mode": "x", "seed": "1"}}),
     "spec.seed = '1', expected an integer"),
    ("note a number", json.dumps({**GOOD, "note": 3}), "note = '3', expected a text or null"),
    ("expected a text", json.dumps({**GOOD, "expected": "1"}), "expected = '1', expected a number or null"),
]


@pytest.mark.parametrize("text,message", [c[1:] for c in READER_CASES], ids=[c[0] for c in READER_CASES])
def test_read_record_names_the_file_and_what_was_expected(tmp_path, text, message):
    path = tmp_path / "trial.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(ParameterError) as raised:
        read_record(path, KIND)
    assert str(raised.value).startswith(f"{path}: {message}") and "\n" not in str(raised.value)


def test_read_record_gives_back_what_was_written(tmp_path):
    assert read_record(write_json(tmp_path / "trial.json", GOOD), KIND) == GOOD
    with pytest.raises(ParameterError, match="no such file"):
        read_record(tmp_path / "none.json", KIND)
    with pytest.raises(ParameterError, match="a directory; give its trial record's JSON file"):
        read_record(tmp_path, KIND)


def test_the_round_trip_and_study_readers_take_their_own_records_only(tmp_path):
    from mdroll.inverse.roundtrip_report import ROUNDTRIP_RECORD
    from mdroll.studies.report import STUDY_RECORD

    study = Path(__file__).resolve().parents[1] / "docs" / "studies" / "quick" / "coupling" / "coupling.json"
    assert read_record(study, STUDY_RECORD)["study"] == "coupling"
    with pytest.raises(ParameterError, match="the record lacks 'rows' .*: not a round-trip record as mdroll invert "
                                             "--round-trip writes it"):
        read_record(study, ROUNDTRIP_RECORD)
    trip = write_json(tmp_path / "roundtrip.json", {"size": "quick", "seconds": 2.0, "rows": [
        {"passes": 2, "L": 1.0, "error": {"H": 0.1}, "covered": {"H": False}}]})
    assert read_record(trip, ROUNDTRIP_RECORD)["rows"][0]["L"] == 1.0
    with pytest.raises(ParameterError, match="the record lacks 'study' .*: not a study record as mdroll study"):
        read_record(trip, STUDY_RECORD)
