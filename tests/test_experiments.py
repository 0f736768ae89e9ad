"""The experiment framework: the ladder, the registry, the record's provenance, the table and
figure writers (mdroll.experiments)."""

from __future__ import annotations

import io
import json

import pytest

from mdroll.errors import ParameterError
from mdroll import __version__
from mdroll.experiments import (SIZES, Figure, Ladder, Registry, markdown_table, provenance, text_table,
                                write_figure, write_figures, write_json)


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
