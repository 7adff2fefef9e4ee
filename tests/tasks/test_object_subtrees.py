"""An object is a body subtree: its joint on one body, its geoms (and mass) on welded child bodies.

robosuite's objects carry a free joint on ``X_main`` and their geoms on child bodies; Meta-World's
bin-picking object ``obj`` likewise. The kind of joint is read from the model when a scene file
leaves ``objects.joints`` out.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin.errors import EnergyMarginError
from energy_margin.integrations.live_model import LiveModelScorer, LiveOptions
from energy_margin.sim.mujoco_index import object_geoms, object_inertials, object_owners
from energy_margin.tasks.scene_model import load_scene
from energy_margin.tasks.scene_task import SceneTask

GROUND = '<geom name="ground" type="plane" size="2 2 0.1"/>'
PUSHER = (
    '<body name="pusher" mocap="true" pos="0 -0.15 0.05"><geom name="pusher" type="box" size="0.15 0.02 0.05"/></body>'
)
# One rigid dumbbell: two boxes 8 cm apart, on one body or on two welded child bodies.
ONE_BODY = (
    '<body name="bell" pos="0 0 0.03"><freejoint/>'
    '<geom type="box" size="0.02 0.02 0.02" pos="0.04 0 0" mass="0.2"/>'
    '<geom type="box" size="0.02 0.03 0.02" pos="-0.04 0 0" mass="0.1"/></body>'
)
CHILD_BODIES = (
    '<body name="bell" pos="0 0 0.03"><freejoint/>'
    '<body name="bell_left" pos="0.04 0 0"><geom type="box" size="0.02 0.02 0.02" mass="0.2"/></body>'
    '<body name="bell_right" pos="-0.04 0 0"><geom type="box" size="0.02 0.03 0.02" mass="0.1"/></body></body>'
)
# A jointless holder whose one child carries the joint: the child is the object.
HOLDER = (
    '<body name="holder" pos="0.3 0 0"><body name="puck" pos="0 0 0.02">'
    '<joint name="px" type="slide" axis="1 0 0"/><joint name="py" type="slide" axis="0 1 0"/>'
    '<geom type="cylinder" size="0.03 0.02" mass="0.1"/></body></body>'
)


def model_of(*bodies: str) -> mujoco.MjModel:
    xml = f'<mujoco><option timestep="0.005"/><worldbody>{GROUND}{PUSHER}{"".join(bodies)}</worldbody></mujoco>'
    return mujoco.MjModel.from_xml_string(xml)


def body(model: mujoco.MjModel, name: str) -> int:
    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))


def test_welded_children_belong_to_the_object_and_jointed_ones_do_not() -> None:
    model = model_of(CHILD_BODIES, HOLDER)
    owner = object_owners(model, [body(model, "bell")])
    assert owner[body(model, "bell")] == owner[body(model, "bell_left")] == owner[body(model, "bell_right")] == 0
    assert owner[body(model, "puck")] == -1 and owner[body(model, "pusher")] == -1
    (geoms,) = object_geoms(model, [body(model, "bell")])
    assert sorted(int(model.geom_bodyid[g]) for g in geoms) == [body(model, "bell_left"), body(model, "bell_right")]


def test_a_one_body_object_keeps_its_body_mass_and_inertia_to_the_bit() -> None:
    model = model_of(ONE_BODY)
    mass, inertia = object_inertials(model, [body(model, "bell")])
    assert mass[0] == model.body_mass[body(model, "bell")]
    assert np.array_equal(inertia[0], model.body_inertia[body(model, "bell")])


def test_a_subtree_has_the_mass_and_inertia_of_the_same_geoms_on_one_body() -> None:
    one, split = model_of(ONE_BODY), model_of(CHILD_BODIES)
    mass, inertia = object_inertials(split, [body(split, "bell")])
    assert mass[0] == pytest.approx(0.3)
    assert mass[0] == pytest.approx(one.body_mass[body(one, "bell")], rel=1e-12)
    # The dumbbell's principal axes are the body's axes: MuJoCo's own inertia of the one body.
    # MuJoCo orders a body's principal moments itself; the dumbbell's principal axes are the body's axes.
    assert sorted(inertia[0]) == pytest.approx(sorted(one.body_inertia[body(one, "bell")]), rel=1e-9)


def scorer(model: mujoco.MjModel, objects: str, **options: object) -> LiveModelScorer:
    return LiveModelScorer(
        model,
        objects=objects,
        capture={"type": "distance", "body": "pusher", "max": 0.3},
        success={"type": "height", "min": 0.0},
        options=LiveOptions(budget_s=None, max_expansions=20, seed=1),
        **options,  # type: ignore[arg-type]
    )


def test_an_object_with_its_geoms_on_child_bodies_is_scored_like_the_same_object_on_one_body() -> None:
    one, split = model_of(ONE_BODY), model_of(CHILD_BODIES)
    first, second = scorer(one, "bell"), scorer(split, "bell")
    assert first.object_names == second.object_names == ("bell",)
    assert np.allclose(first.task.loaded.object_half_extents, second.task.loaded.object_half_extents)
    assert np.allclose(first.task.loaded.object_radius, second.task.loaded.object_radius)
    data_one, data_split = mujoco.MjData(one), mujoco.MjData(split)
    for data, model in ((data_one, one), (data_split, split)):
        mujoco.mj_forward(model, data)
    a, b = first.score(data_one), second.score(data_split)
    assert 0.0 <= a["capture_score"] <= 1.0 and 0.0 <= b["capture_score"] <= 1.0
    assert a["expansions"] == b["expansions"] == 20


def test_the_joint_kind_is_read_from_the_model() -> None:
    assert scorer(model_of(ONE_BODY), "bell").task.loaded.spec.object_joints == "free"
    # Matching the jointless holder resolves to the puck that carries the joints (upright slides).
    model = model_of(HOLDER)
    upright = scorer(model, "holder")
    assert upright.object_names == ("puck",)
    assert upright.task.loaded.spec.object_joints == "upright"
    # The puck sits 0.3 m along x on its holder: its position is measured in the world.
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert np.allclose(upright.frame(data).object_pos[0], [0.3, 0.0, 0.02])


def test_an_object_without_any_joint_is_one_line() -> None:
    model = model_of('<body name="rock" pos="0 0.5 0.03"><geom type="sphere" size="0.03"/></body>')
    with pytest.raises(EnergyMarginError, match=r"object body 'rock' .* has no joint: it cannot move"):
        scorer(model, "rock")


def test_a_scene_file_without_objects_joints_reads_them_from_the_model(tmp_path: Path) -> None:
    (tmp_path / "model.xml").write_text(
        f'<mujoco><option timestep="0.005"/><worldbody>{GROUND}{PUSHER}{CHILD_BODIES}</worldbody></mujoco>'
    )
    (tmp_path / "scene.toml").write_text(
        'schema_version = 1\nmjcf = "model.xml"\n[objects]\nbodies = ["bell"]\n[motion]\nduration = 1.0\n'
        '[capture]\nregion = { type = "distance", body = "pusher", max = 0.3 }\n'
        '[success]\nregion = { type = "height", min = 0.0 }\n'
    )
    task = SceneTask(loaded=load_scene(tmp_path / "scene.toml"))
    assert task.loaded.spec.object_joints == "free"
    assert task.build_scene(1, 0.5).objects[0].mass == pytest.approx(0.3)
