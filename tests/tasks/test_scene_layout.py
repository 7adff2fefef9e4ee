"""Start layouts: the default separation from the objects' footprint in the plane normal to gravity."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.errors import InvalidDataError
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_layout import Separation, start_separation
from energy_margin.tasks.scene_model import load_scene
from energy_margin.tasks.scene_objects import object_footprints

BOX_A = '<body name="box_a" pos="-0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>'
BOX_B = '<body name="box_b" pos="0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>'
# Two 12 cm cans of radius 3.3 cm standing upright: footprint radius 0.033 m, bounding radius 0.0685 m.
CAN = '<freejoint/><geom type="cylinder" size="0.033 0.06" mass="0.1"/></body>'
CANS = {BOX_A: '<body name="box_a" pos="-0.1 0 0.06">' + CAN, BOX_B: '<body name="box_b" pos="0.1 0 0.06">' + CAN}
START = "[randomize.start]\nx = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n"
# A strip 0.1 m long: two cans fit 0.066 m apart, never 0.137 m apart.
STRIP = "[randomize.start]\nx = [-0.05, 0.05]\ny = [0.02, 0.02]\nyaw = [-0.3, 0.3]\n"
CAN_BOUND = float(np.hypot(0.033, 0.06))


def test_an_upright_can_has_its_radius_as_footprint(make_scene) -> None:
    loaded = load_scene(make_scene(model_replace=CANS))
    assert loaded.object_footprint == pytest.approx([0.033, 0.033])
    assert loaded.object_radius == pytest.approx([CAN_BOUND, CAN_BOUND])
    rule = start_separation(loaded)
    assert rule.distance == pytest.approx(0.066) and rule.planar
    assert rule.source == "twice the largest footprint radius, in the x-y plane"


def test_scene_prints_each_objects_footprint(make_scene, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scene", str(make_scene(model_replace=CANS)), "--no-picture"]) == 0
    out = capsys.readouterr().out
    assert "  box_a: mass 0.1 kg," in out
    assert "bounding radius 0.0685 m, footprint radius in x-y 0.033 m" in out
    assert "min separation 0.066 m, twice the largest footprint radius, in the x-y plane (default)" in out


def test_a_box_reaches_its_corner_and_a_lying_can_its_bound(make_scene) -> None:
    # A 6 cm box: its x-y corner, 0.03 sqrt(2) m, below its 3-D corner 0.03 sqrt(3) m.
    loaded = load_scene(make_scene())
    assert loaded.object_footprint == pytest.approx([0.03 * np.sqrt(2)] * 2)
    # A can lying along y reaches 0.06 m along its axis and 0.033 m across: never above its bounding radius.
    lying = {BOX_B: CANS[BOX_B].replace('pos="0.1 0 0.06"', 'pos="0.1 0 0.033" quat="0.7071068 0.7071068 0 0"')}
    loaded = load_scene(make_scene(model_replace=lying))
    raw = object_footprints(loaded.model, loaded.object_bodies, loaded.initial_qpos)
    assert raw[1] == pytest.approx(0.06 + 0.033)
    assert loaded.object_footprint[1] == pytest.approx(CAN_BOUND)


def test_the_file_value_a_pile_and_sideways_gravity_keep_the_3d_rule(make_scene) -> None:
    given = load_scene(make_scene(model_replace=CANS, replace={START: START + "min_separation = 0.2\n"}))
    assert start_separation(given) == Separation(0.2, planar=False, source="randomize.start.min_separation")
    pile = '[randomize.start]\nmode = "pile"\nlow = [-0.2, 0.1, 0.1]\nhigh = [0.2, 0.3, 0.3]\n'
    rule = start_separation(load_scene(make_scene(model_replace=CANS, replace={START: pile})))
    assert rule.distance == pytest.approx(2 * CAN_BOUND) and not rule.planar
    sideways = {**CANS, '<option timestep="0.01"/>': '<option timestep="0.01" gravity="0 -9.81 0"/>'}
    rule = start_separation(load_scene(make_scene(model_replace=sideways)))
    assert rule.distance == pytest.approx(2 * CAN_BOUND) and not rule.planar


def test_the_planar_rule_measures_in_x_y_only() -> None:
    rule = Separation(0.066, planar=True, source="")
    placed = np.array([[0.0, 0.0, 0.06]])
    assert not rule.apart(placed, np.array([0.05, 0.0, 0.5]))  # above it, 0.05 m apart in x-y
    assert rule.apart(placed, np.array([0.07, 0.0, 0.06]))
    assert not Separation(0.066, planar=False, source="").apart(placed, np.array([0.0, 0.0, 0.12]))
    assert Separation(0.066, planar=False, source="").apart(placed, np.array([0.05, 0.0, 0.5]))
    assert rule.apart(np.empty((0, 3)), np.zeros(3))


def test_cans_fit_a_strip_the_bounding_radius_refused(make_scene) -> None:
    scene = make_scene(model_replace=CANS, replace={START: STRIP})
    task = get_task("scene", {"scene_file": str(scene)})
    for seed in range(8):
        initial = task.sample_trajectory(np.random.default_rng(seed), 2).initial
        gap = float(np.linalg.norm(initial.object_pos[0, :2] - initial.object_pos[1, :2]))
        assert 0.066 < gap <= 0.1
        assert initial.object_pos[:, 2] == pytest.approx([0.06, 0.06])
    # The same strip with the bounding radius's separation finds no room.
    wide = make_scene(model_replace=CANS, replace={START: STRIP + f"min_separation = {2 * CAN_BOUND}\n"})
    with pytest.raises(InvalidDataError, match=r"cannot place 2 objects 0\.137 m apart"):
        get_task("scene", {"scene_file": str(wide)}).sample_trajectory(np.random.default_rng(0), 2)


def test_a_left_out_axis_comes_from_the_initial_keyframe(make_scene, capsys: pytest.CaptureFixture[str]) -> None:
    # box_b sits at y = 0 in the model and at y = 0.05 in the keyframe: a start that draws x only
    # keeps the keyframe's y and z, not the model's.
    keyframe = (
        '  <keyframe><key name="start" qpos="-0.06 0 0.03 1 0 0 0 0.06 0.05 0.04 1 0 0 0" '
        'mpos="0 -0.15 0.03" mquat="1 0 0 0"/></keyframe>\n</mujoco>'
    )
    only_x = "[randomize.start]\nx = [-0.12, 0.12]\n"
    scene = make_scene(
        model_replace={"</mujoco>": keyframe},
        replace={START: only_x, "duration = 1.5\n": 'duration = 1.5\ninitial_keyframe = "start"\n'},
    )
    task = get_task("scene", {"scene_file": str(scene)})
    initial = task.sample_trajectory(np.random.default_rng(0), 2).initial
    assert initial.object_pos[:, 1:] == pytest.approx(np.array([[0.0, 0.03], [0.05, 0.04]]))
    assert main(["scene", str(scene), "--no-picture"]) == 0
    assert "y the initial keyframe's (default), z the initial keyframe's (default)" in capsys.readouterr().out
    # Without the keyframe the same start keeps the model's y and z.
    plain = get_task("scene", {"scene_file": str(make_scene(replace={START: only_x}))})
    initial = plain.sample_trajectory(np.random.default_rng(0), 2).initial
    assert initial.object_pos[:, 1:] == pytest.approx(np.array([[0.0, 0.03], [0.0, 0.03]]))
