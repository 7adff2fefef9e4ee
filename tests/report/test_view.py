"""The interactive view: every node in a self-contained page that loads in headless Chromium."""

from __future__ import annotations

import base64
import json
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.report.frame_tree import analysed_tree

pytest.importorskip("plotly")


def plotly_traces(page: str) -> list[dict[str, Any]]:
    """The trace list of the page's ``Plotly.newPlot`` call, typed arrays decoded."""
    start = page.rindex("Plotly.newPlot(")  # the figure's call, after plotly.js (which may name it)
    start = page.index("[", page.index(",", start))
    traces, _ = json.JSONDecoder().raw_decode(page[start:])

    def decode(value: Any) -> Any:
        if isinstance(value, dict) and "bdata" in value:
            array = np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"]))
            if "shape" in value:
                array = array.reshape([int(n) for n in str(value["shape"]).split(",")])
            return array
        if isinstance(value, dict):
            return {key: decode(item) for key, item in value.items()}
        if isinstance(value, list):
            return [decode(item) for item in value]
        return value

    return [decode(trace) for trace in traces]


def script_sources(page: str) -> list[str]:
    """The ``src`` of every script element of an HTML page."""

    class Scripts(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.sources: list[str] = []

        def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
            if tag == "script":
                self.sources += [value or "" for name, value in attrs if name == "src"]

    parser = Scripts()
    parser.feed(page)
    return parser.sources


def _write_view(analysed: Path, tmp_path: Path, trajectory: int = 1, frame: int = 2) -> Path:
    out = tmp_path / "view.html"
    assert main(["view", str(analysed), "--trajectory", str(trajectory), "--frame", str(frame), "--out", str(out)]) == 0
    return out


def test_view_holds_every_node_of_the_analysed_tree(analysed: Path, tmp_path: Path) -> None:
    page = _write_view(analysed, tmp_path).read_text(encoding="utf-8")
    tree = analysed_tree(analysed, 1, 2)
    assert tree.matches_stored
    traces = {trace["name"].split(" (")[0]: trace for trace in plotly_traces(page)}
    assert {"objects", "end-effector", "statics", "capture region", "success region"} <= set(traces)
    nodes = traces["tree nodes"]
    custom = np.asarray(nodes["customdata"], dtype=float)
    m, n = tree.field.object_pos.shape[:2]
    assert custom.shape == (m * n, 5)
    assert set(custom[:, 0].astype(int)) == set(range(m))
    positions = np.column_stack([nodes["x"], nodes["y"], nodes["z"]])
    np.testing.assert_allclose(positions, tree.field.object_pos.reshape(-1, 3))
    np.testing.assert_allclose(custom[:, 2], np.repeat(tree.field.parents, n))
    edges = traces["edges to parents"]
    assert edges["visible"] == "legendonly"
    assert len(edges["x"]) == 3 * (m - 1) * n
    # plotly.js is inside the page: no script is loaded from elsewhere.
    assert script_sources(page) == [] and len(page) > 3_000_000


def test_view_bad_input_is_one_line(
    analysed: Path, tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cases = [
        ([str(analysed), "--trajectory", "7", "--frame", "0"], "has no trajectory 7 (trajectories 0 to 1)"),
        ([str(analysed), "--trajectory", "0", "--frame", "3"], "has no frame 3 (frames 0 to 2)"),
        ([str(tiny_dataset), "--trajectory", "0", "--frame", "0"], "has no scores.csv; run `energy-margin analyze`"),
        ([str(tmp_path / "none"), "--trajectory", "0", "--frame", "0"], "does not exist"),
        (
            [str(analysed), "--trajectory", "0", "--frame", "0", "--out", str(tmp_path / "no" / "v.html")],
            "is not a directory",
        ),
    ]
    for arguments, message in cases:
        assert main(["view", *arguments]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "no").exists()


@pytest.mark.slow
def test_view_loads_in_headless_chromium_without_errors(
    analysed: Path, tmp_path: Path, chromium_page: tuple[Any, list[str]]
) -> None:
    page, errors = chromium_page
    out = _write_view(analysed, tmp_path)
    tree = analysed_tree(analysed, 1, 2)
    requests: list[str] = []
    page.on("request", lambda request: requests.append(request.url))
    page.goto(out.as_uri())
    page.wait_for_function("() => document.querySelector('.plotly-graph-div')?._fullLayout !== undefined")
    names = page.evaluate("() => document.querySelector('.plotly-graph-div').data.map(t => t.name)")
    node_trace = next(i for i, name in enumerate(names) if name.startswith("tree nodes"))
    count = page.evaluate(f"() => document.querySelector('.plotly-graph-div')._fullData[{node_trace}].x.length")
    assert count == tree.field.nodes * tree.field.object_pos.shape[1]
    # The WebGL scene was drawn: a canvas of the page's size.
    assert page.evaluate("() => document.querySelectorAll('.gl-container canvas').length") >= 1
    edges = names.index("edges to parents")
    page.get_by_text("show edges").click()
    assert page.evaluate(f"() => document.querySelector('.plotly-graph-div').data[{edges}].visible") is True
    assert errors == []
    # Opens with no server and no network: the page is the only request.
    assert {url for url in requests if not url.startswith("data:")} == {out.as_uri()}
