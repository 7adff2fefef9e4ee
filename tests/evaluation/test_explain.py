"""The account of failed trajectories: which object left which region, at which frame, time and position."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.evaluation.explain import (
    FailureExplanation,
    explain_failures,
    format_explanations,
    object_membership,
)
from energy_margin.tasks.region_sets import AtLeast
from tiny_scene import TINY_SCENE

# Where object 1 of trajectory 0 is moved from frame 1 on: far from the pusher and the goal.
AWAY = np.array([3.0, 3.0, 0.0])


@pytest.fixture
def wandering(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> Path:
    """The tiny pushing dataset with object 1 of trajectory 0 away from frame 1 on (so trajectory 0 fails)."""
    dataset = load_dataset(tiny_dataset)
    positions = dataset.arrays["object_pos"].copy()
    positions[0, 1:, 1] = AWAY
    captured = dataset.arrays["captured"].copy()
    in_success = dataset.arrays["in_success"].copy()
    captured[0, 1:] = False
    in_success[0, :] = False
    rewrite_frames(tiny_dataset, object_pos=positions, captured=captured, in_success=in_success)
    return tiny_dataset


def test_an_object_that_leaves_is_named_with_its_frame_time_and_position(wandering: Path) -> None:
    dataset = load_dataset(wandering)
    assert list(np.flatnonzero(~dataset.success_labels())) == [0, 1]
    explanations = explain_failures(dataset)
    assert [item.trajectory for item in explanations] == [0, 1]
    first = explanations[0]
    assert first.capture_lost_frame == 1
    assert first.capture_needed == 2 and first.success_needed == 2
    assert [(e.kind, e.object, e.frame) for e in first.events] == [
        ("left_capture", 1, 1),
        ("missed_success", 1, 2),
    ]
    left = first.events[0]
    assert left.name == "object1"
    assert left.time_s == pytest.approx(float(dataset.arrays["frame_time"][0, 1]))
    assert left.position == pytest.approx(tuple(AWAY))
    # Trajectory 1 stays captured but both objects end outside the success region.
    second = explanations[1]
    assert second.capture_lost_frame is None
    last = dataset.n_frames - 1
    assert [(e.kind, e.object, e.frame) for e in second.events] == [
        ("missed_success", 0, last),
        ("missed_success", 1, last),
    ]
    assert second.events[1].position == pytest.approx(tuple(dataset.arrays["object_pos"][1, last, 1]))


def test_a_successful_trajectory_is_not_explained(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    assert bool(dataset.success_labels()[0])
    assert [item.trajectory for item in explain_failures(dataset)] == list(np.flatnonzero(~dataset.success_labels()))
    assert 0 not in [item.trajectory for item in explain_failures(dataset)]


def test_the_explanation_round_trips_through_its_dictionary(wandering: Path) -> None:
    explanations = explain_failures(load_dataset(wandering))
    values = [item.to_dict() for item in explanations]
    assert values[0]["events"][0]["position"] == pytest.approx(list(AWAY))
    assert [FailureExplanation.from_dict(value) for value in values] == list(explanations)


def test_the_text_says_which_object_left_when_and_where(wandering: Path) -> None:
    text = format_explanations(explain_failures(load_dataset(wandering)), 2)
    assert text.splitlines()[0] == "failed trajectories: 2"
    assert "trajectory 0: capture lost at frame 1; capture needs every object, success every object" in text
    assert "  object 1 left the capture region at frame 1 (t = 1.000 s) at (3.000, 3.000, 0.000) m" in text
    assert format_explanations((), 2) == "failed trajectories: none"


def test_an_at_least_set_is_tested_object_by_object(wandering: Path) -> None:
    dataset = load_dataset(wandering)
    frame = dataset.frame(0, 1)
    region = dataset.task.capture_region(frame)
    inside, needed = object_membership(region, frame)
    assert list(inside) == [True, False] and needed == 2
    # "At least 1 object" holds for every object of the frame, yet object 1 alone is outside.
    assert bool(np.all(AtLeast(1, region).contains(frame.object_pos, frame.object_vel)))
    inside, needed = object_membership(AtLeast(1, region), frame)
    assert list(inside) == [True, False] and needed == 1


def test_a_scene_files_at_least_set_is_explained_object_by_object(make_scene, tmp_path: Path) -> None:
    # Success needs one box of two within 1 mm of a goal no box reaches: every trajectory fails,
    # and each box is named at the last frame though the set needs only one.
    success = '[success]\nat_least = 1\nregion = { type = "distance", site = "goal", max = 0.001 }\n'
    old = TINY_SCENE[TINY_SCENE.index("[success]") :]
    scene = make_scene(replace={old: success})
    out = tmp_path / "set"
    assert main(["generate", "--scene", str(scene), "--trajectories", "2", "--frames", "3", "--out", str(out)]) == 0
    dataset = load_dataset(out)
    explanations = explain_failures(dataset)
    assert [item.trajectory for item in explanations] == [0, 1]
    for item in explanations:
        assert item.success_needed == 1 and item.capture_needed == 2
        missed = [(e.name, e.frame) for e in item.events if e.kind == "missed_success"]
        assert missed == [("box_a", 2), ("box_b", 2)]
    text = format_explanations(explanations, 2)
    assert "success at least 1 of 2 objects" in text
    assert "  box_a (object 0) missed the success region at frame 2" in text


def test_an_object_outside_at_the_first_frame_started_outside(
    wandering: Path, rewrite_frames: Callable[..., None]
) -> None:
    dataset = load_dataset(wandering)
    positions = dataset.arrays["object_pos"].copy()
    positions[0, 0, 1] = AWAY
    rewrite_frames(wandering, object_pos=positions)
    first = explain_failures(load_dataset(wandering))[0]
    event = first.events[0]
    assert (event.kind, event.object, event.frame) == ("left_capture", 1, 0)
    text = format_explanations((first,), 2)
    assert "  object 1 started outside the capture region at frame 0 (t = 0.000 s) at (3.000, 3.000, 0.000) m" in text
