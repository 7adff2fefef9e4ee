"""The report's table of failed trajectories."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.report.html_failures import failures_html


def test_the_table_names_the_object_the_frame_and_the_position(
    tiny_dataset: Path, rewrite_frames: Callable[..., None]
) -> None:
    dataset = load_dataset(tiny_dataset)
    positions = dataset.arrays["object_pos"].copy()
    positions[0, 1:, 1] = [3.0, 3.0, 0.0]
    in_success = dataset.arrays["in_success"].copy()
    in_success[0, :] = False
    rewrite_frames(tiny_dataset, object_pos=positions, in_success=in_success)
    page = failures_html("pushing", load_dataset(tiny_dataset))
    assert page.startswith("<p>pushing: 2 of 2 trajectories failed;")
    assert (
        "<tr><td>0</td><td>object1</td><td>left the capture region</td><td>1</td><td>1.000</td>"
        "<td>(3.000, 3.000, 0.000)</td></tr>" in page
    )
    assert page.count("<tr><td>") == 4  # object 1 twice in trajectory 0, both objects once in trajectory 1
    assert "the first 2 of 4 rows" in failures_html("pushing", load_dataset(tiny_dataset), max_rows=2)
    assert failures_html("pushing", load_dataset(tiny_dataset), max_rows=2).count("<tr><td>") == 2


def test_a_set_without_failures_says_so(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    dataset = load_dataset(tiny_dataset)
    rewrite_frames(tiny_dataset, in_success=np.ones_like(dataset.arrays["in_success"]))
    assert failures_html("pushing", load_dataset(tiny_dataset)) == "<p>pushing: every trajectory succeeded.</p>"
