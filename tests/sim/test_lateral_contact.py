"""The ``sphere`` lateral contact of upright cylinders against the cylinders' own contacts.

The stand-in is a sphere of the cylinder's radius at its centre; it takes every contact but the
ground's. In the plane through the centres it is the cylinder's circle, so what must not change:
every lateral contact (pair, depth, normal) with other objects, the pusher and the wall, the
sliding friction on the ground, the momentum exchanged in a collision, the push of the pusher, and
the energy bookkeeping. What does change: the engine reports a cylinder's line contact with a
face as several identical rows (two in MuJoCo 4.0, one in 3.3: :func:`line_contact_rows`), the
sphere's as one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.tasks import PushingTask, command_robot, get_task
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState
from releases import LATERAL_TOLERANCE, for_release

MODES = ("geometry", "sphere")

# An upright cylinder pressed 1 mm into a box's face.
LINE_CONTACT = """<mujoco><worldbody>
<geom type="box" size="0.5 0.05 0.1" pos="0 0.1 0.1"/>
<body pos="0 0.001 0.015"><freejoint/><geom type="cylinder" size="0.05 0.015"/></body>
</worldbody></mujoco>"""


def line_contact_rows() -> int:
    """The rows the installed MuJoCo reports for a cylinder's line contact with a face."""
    model = mujoco.MjModel.from_xml_string(LINE_CONTACT)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon >= 1 and np.allclose(data.contact.dist, -0.001, rtol=0, atol=1e-5)
    return int(data.ncon)


def _pushing(n_objects: int, friction: float, *, lateral: str, ground: str = "geometry") -> MujocoSimulator:
    task = get_task("pushing", {"lateral_contact": lateral, "ground_contact": ground})
    return MujocoSimulator(task.build_scene(n_objects, friction))


def _lateral_contacts(simulator: MujocoSimulator) -> list[tuple[str, str, float, tuple[float, ...]]]:
    """Every contact but the ground's: sorted body pair, depth (m) and unsigned normal."""
    model, data = simulator.model, simulator.data
    found = []
    for contact in data.contact[: data.ncon]:
        geoms = (contact.geom1, contact.geom2)
        if any(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) == "ground" for g in geoms):
            continue
        if any((mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").endswith("_footprint") for g in geoms):
            continue
        bodies = sorted(
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])) or "world" for g in geoms
        )
        normal = tuple(np.abs(contact.frame[:3]))
        found.append((bodies[0], bodies[1], float(contact.dist), normal))
    return sorted(found)


def _packed_frame(task: PushingTask, rng: np.random.Generator, n_objects: int) -> tuple[FrameState, float]:
    """A frame whose cylinders touch each other, the pusher and (some) the wall."""
    trajectory = task.sample_trajectory(rng, n_objects)
    frame = trajectory.initial
    pos = frame.object_pos.copy()
    pos[:, 0] = pos[0, 0] + 0.098 * np.arange(n_objects) + rng.uniform(-0.003, 0.003, n_objects)
    pos[:, 1] = pos[0, 1] + rng.uniform(-0.01, 0.01, n_objects)
    # The last object presses on the wall.
    pos[-1, 1] = task.config.wall_y - task.config.object_radius + rng.uniform(0.0, 0.004)
    robot_q = frame.robot_q.copy()
    robot_q[:2] = [pos[1, 0], pos[:-1, 1].min() - 0.149]
    return dataclasses.replace(frame, object_pos=pos, robot_q=robot_q), trajectory.friction


def test_sphere_needs_upright_objects(make_block_scene: Callable[..., Scene]) -> None:
    with pytest.raises(InvalidParameterError, match="upright"):
        dataclasses.replace(make_block_scene(1, motion="free"), lateral_contact="sphere")
    with pytest.raises(InvalidParameterError, match="lateral_contact"):
        dataclasses.replace(make_block_scene(1, motion="upright"), lateral_contact="capsule")
    with pytest.raises(EnergyMarginError, match="lateral_contact"):
        get_task("pushing", {"lateral_contact": "capsule"})


@pytest.mark.parametrize("ground", ["geometry", "footprint"])
def test_lateral_contacts_are_the_cylinders(ground: str) -> None:
    # Packed layouts: every pair that touches (other than through the ground) touches with the
    # sphere, at the same depth and along the same normal. Differences measured: depth < 1e-7 m
    # (1.5e-7 m with MuJoCo 3.3);
    # object-object normals within 4e-3 (the engine's convex pair is iterative; the sphere pair
    # gives the exact centre line); with the pusher and the wall depth < 1e-8 m, normals < 1e-6.
    task = PushingTask()
    rng = np.random.default_rng(11)
    checked = {"object": 0, "pusher": 0, "world": 0}
    rows = line_contact_rows()
    tolerance = for_release(LATERAL_TOLERANCE, "the tolerances")
    for _ in range(20):
        frame, friction = _packed_frame(task, rng, 4)
        contacts, counts = {}, {}
        for mode in MODES:
            simulator = _pushing(4, friction, lateral=mode, ground=ground)
            simulator.reset(frame)
            # One entry per pair: a line contact's two ends have the same depth and normal.
            found = _lateral_contacts(simulator)
            contacts[mode] = {c[:2]: c[2:] for c in found}
            counts[mode] = sorted(c[:2] for c in found)
            if mode == "sphere":
                model, data = simulator.model, simulator.data
                for contact in data.contact[: data.ncon]:
                    names = sorted(
                        (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").rsplit("_", 1)[-1]
                        for g in (contact.geom1, contact.geom2)
                    )
                    # Spheres take every contact; the cylinder itself only the ground's.
                    assert "sphere" in names or "ground" in names or "footprint" in names, names
        # One row per pair with the sphere; the engine's line contacts with a face have ``rows``.
        assert sorted(set(counts["geometry"])) == counts["sphere"]
        assert all(
            counts["geometry"].count(pair) == (rows if "object" not in pair[1] else 1) for pair in counts["sphere"]
        )
        assert sorted(contacts["sphere"]) == sorted(contacts["geometry"])
        for pair, (depth, normal) in contacts["sphere"].items():
            reference_depth, reference_normal = contacts["geometry"][pair]
            assert depth == pytest.approx(reference_depth, abs=tolerance["object"])
            np.testing.assert_allclose(normal, reference_normal, atol=4e-3)
            if "pusher" in pair or "world" in pair:
                assert depth == pytest.approx(reference_depth, abs=tolerance["face"])
                np.testing.assert_allclose(normal, reference_normal, atol=tolerance["face_normal"])
                checked["pusher" if "pusher" in pair else "world"] += 1
            else:
                first, second = (int(name.removeprefix("object")) for name in pair)
                centre_line = frame.object_pos[second, :2] - frame.object_pos[first, :2]
                centre_line = np.abs(centre_line) / np.linalg.norm(centre_line)
                np.testing.assert_allclose(normal[:2], centre_line, atol=1e-9)
                checked["object"] += 1
    assert checked["object"] > 20 and checked["pusher"] > 5 and checked["world"] > 5, checked


def test_the_ground_contact_is_the_cylinders() -> None:
    # The stand-in never touches the floor: the ground contacts are the cylinder's (its rim).
    counts = {}
    for mode in MODES:
        simulator = _pushing(3, 0.2, lateral=mode)
        z = -0.015 + 0.015
        pos = np.array([[0.5, 0.5, z], [1.0, 0.5, z], [1.5, 0.5, z]])
        simulator.reset(FrameState(pos, np.tile([1.0, 0, 0, 0], (3, 1)), np.zeros((3, 6)), np.zeros(4), np.zeros(4)))
        simulator.step(5)
        model, data = simulator.model, simulator.data
        names = [
            {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in (c.geom1, c.geom2)}
            for c in data.contact[: data.ncon]
        ]
        assert not any(any((n or "").endswith("_sphere") for n in pair) and "ground" in pair for pair in names)
        counts[mode] = data.ncon
        # Resting objects stay at rest on the ground.
        np.testing.assert_allclose(simulator.object_positions()[:, 2], z, atol=1e-3)
    assert counts["sphere"] == counts["geometry"]


@pytest.mark.parametrize("ground", ["geometry", "footprint"])
def test_sliding_and_collision_are_unchanged(ground: str) -> None:
    # One cylinder slides into a resting one: both come to rest at the same places, with the same
    # friction work, whichever lateral contact carries the collision.
    results = {}
    for mode in MODES:
        simulator = _pushing(2, 0.2, lateral=mode, ground=ground)
        z = 0.0
        pos = np.array([[0.6, 0.8, z], [0.8, 0.81, z]])
        velocity = np.zeros((2, 6))
        velocity[0, 0] = 1.2
        simulator.reset(FrameState(pos, np.tile([1.0, 0, 0, 0], (2, 1)), velocity, np.zeros(4), np.zeros(4)))
        work = simulator.step(120, track_friction_work=True)
        results[mode] = (simulator.object_positions()[:, :2].copy(), work)
    positions, work = results["sphere"]
    reference_positions, reference_work = results["geometry"]
    # The struck object moved (the collision happened) and both end where the cylinders do.
    assert reference_positions[1, 0] > 0.85
    np.testing.assert_allclose(positions, reference_positions, atol=2e-3)
    assert work == pytest.approx(reference_work, rel=0.02)


def test_pushed_by_the_pusher_as_the_cylinder() -> None:
    # The pusher's face drives one cylinder for 0.75 s: it ends where the cylinder's own contact
    # takes it (measured: 0.08 mm apart after 0.25 m).
    ends = {}
    for mode in MODES:
        task = get_task("pushing", {"lateral_contact": mode})
        simulator = MujocoSimulator(task.build_scene(1, 0.2))
        pos = np.array([[1.0, 0.8, 0.0]])
        robot_q = np.array([1.02, 0.8 - 0.15, 0.0, 0.0])
        simulator.reset(FrameState(pos, np.array([[1.0, 0, 0, 0]]), np.zeros((1, 6)), robot_q, np.zeros(4)))
        for _ in range(90):
            simulator.set_robot_force(np.array([0.0, 12.0, 0.0, 0.0]))
            simulator.step(1)
        ends[mode] = (simulator.object_positions()[0, :2].copy(), simulator.robot_positions()[:2].copy())
    # It was pushed (and not as far as the wall at y = 1.55).
    assert 1.0 < ends["geometry"][0][1] < 1.5
    np.testing.assert_allclose(ends["sphere"][0], ends["geometry"][0], atol=2e-3)
    np.testing.assert_allclose(ends["sphere"][1], ends["geometry"][1], atol=2e-3)


def test_scripted_pushing_is_stable_with_spheres() -> None:
    # Whole scripted roll-outs with footprints and spheres: objects stay on the ground, nothing
    # explodes, and the pushed pile moves with the pusher as with the cylinders' own contacts.
    task = get_task("pushing", {"lateral_contact": "sphere", "ground_contact": "footprint"})
    rng = np.random.default_rng(7)
    trajectory = task.sample_trajectory(rng, 5)
    simulator = MujocoSimulator(task.build_scene(5, trajectory.friction, trajectory.drive))
    simulator.reset(trajectory.initial)
    rest = task.config.ground_z + task.config.object_half_height
    start = simulator.object_positions()[:, 1].mean()
    dt = simulator.timestep
    for step in range(round(task.config.duration / dt)):
        command_robot(task, simulator, trajectory.drive, step * dt, np.random.default_rng(step))
        simulator.step(1)
        z = simulator.object_positions()[:, 2]
        assert np.all(np.abs(z - rest) < 3e-3), (step, z)
        velocity = simulator.object_velocities()
        assert np.abs(velocity[:, :3]).max() < 3.0, step
        assert np.abs(velocity[:, 3:]).max() < 50.0, step
    assert simulator.object_positions()[:, 1].mean() > start + 0.1
