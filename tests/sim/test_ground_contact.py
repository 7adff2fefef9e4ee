"""The ``footprint`` ground contact of upright objects against the engine's own rim contacts.

The footprint replaces the (up to four) rim contacts of an upright cylinder or box with the ground
by one contact at the base centre plus the rim's spin resistance as yaw-joint dry friction. What
must not change: every lateral contact (the object's own shape against other objects, the pusher
and walls), the sliding friction, the spin friction, and the energy bookkeeping.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from energy_margin.errors import InvalidParameterError
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.tasks import PushingTask, command_robot, get_task
from energy_margin.world.scene import Scene
from energy_margin.world.state import FrameState

G = 9.81


def _both(scene: Scene) -> dict[str, MujocoSimulator]:
    return {
        mode: MujocoSimulator(dataclasses.replace(scene, ground_contact=mode)) for mode in ("geometry", "footprint")
    }


def _launch(simulator: MujocoSimulator, velocity: list[float]) -> None:
    half_height = simulator.scene.objects[0].geom.size[-1]
    simulator.reset(
        FrameState(
            np.array([[0.0, 0.0, half_height]]),
            np.array([[1.0, 0.0, 0.0, 0.0]]),
            np.array([velocity]),
            np.zeros(0),
            np.zeros(0),
        )
    )


def test_footprint_needs_upright_objects(make_block_scene: Callable[..., Scene]) -> None:
    with pytest.raises(InvalidParameterError, match="upright"):
        dataclasses.replace(make_block_scene(1, motion="free"), ground_contact="footprint")
    with pytest.raises(InvalidParameterError, match="ground_contact"):
        dataclasses.replace(make_block_scene(1, motion="upright"), ground_contact="patch")


@pytest.mark.parametrize("shape", ["cylinder", "box"])
def test_one_ground_contact_per_object(make_block_scene: Callable[..., Scene], shape: str) -> None:
    simulators = _both(make_block_scene(3, shape=shape, motion="upright", friction=0.4))
    counts = {}
    for mode, simulator in simulators.items():
        half_height = simulator.scene.objects[0].geom.size[-1]
        pos = np.array([[0.0, 0.0, half_height], [0.5, 0.0, half_height], [1.0, 0.0, half_height]])
        simulator.reset(FrameState(pos, np.tile([1.0, 0, 0, 0], (3, 1)), np.zeros((3, 6)), np.zeros(0), np.zeros(0)))
        simulator.step(5)
        counts[mode] = simulator.data.ncon
    assert counts["footprint"] == 3
    assert counts["geometry"] > 3


@pytest.mark.parametrize("shape", ["cylinder", "box"])
@pytest.mark.parametrize("timestep", [1 / 120, 1 / 240])
def test_sliding_friction_is_unchanged(make_block_scene: Callable[..., Scene], shape: str, timestep: float) -> None:
    # Launched at 1 m/s, the object slides v0^2 / (2 mu g) and friction removes 1/2 m v0^2.
    mass, mu, v0 = 0.5, 0.3, 1.0
    results = {}
    for mode, simulator in _both(
        make_block_scene(1, shape=shape, motion="upright", friction=mu, timestep=timestep, mass=mass)
    ).items():
        _launch(simulator, [v0, 0.0, 0.0, 0.0, 0.0, 0.0])
        work = simulator.step(round(0.6 / timestep), track_friction_work=True)
        results[mode] = (simulator.object_positions()[0, 0], work)
    # Measured: 0.1658 m (footprint) against 0.1659 m (rim contacts), both -0.25 J.
    assert results["footprint"][0] == pytest.approx(results["geometry"][0], rel=0.005)
    assert results["footprint"][1] == pytest.approx(-0.5 * mass * v0**2, rel=0.02)


@pytest.mark.parametrize("shape", ["cylinder", "box"])
def test_spin_friction_matches_the_rim_contacts(make_block_scene: Callable[..., Scene], shape: str) -> None:
    mass, mu, spin = 0.5, 0.3, 10.0
    stopped_after = {}
    lost = {}
    for mode, simulator in _both(make_block_scene(1, shape=shape, motion="upright", friction=mu, mass=mass)).items():
        _launch(simulator, [0.0, 0.0, 0.0, 0.0, 0.0, spin])
        energy = simulator.mechanical_energy()
        work = 0.0
        steps = 0
        while simulator.object_velocities()[0, 5] > 1e-3 and steps < 200:
            work += simulator.step(1, track_friction_work=True)
            steps += 1
        stopped_after[mode] = steps
        lost[mode] = (simulator.mechanical_energy() - energy, work)
    # Measured: 14 against 15 steps (cylinder), 13 against 13 (box).
    assert abs(stopped_after["footprint"] - stopped_after["geometry"]) <= 2
    # The yaw joint's dry friction is counted as friction work: it removes the spin energy.
    energy_change, work = lost["footprint"]
    assert work < 0
    assert work == pytest.approx(energy_change, rel=0.05)


def test_spinning_does_not_change_the_slide(make_block_scene: Callable[..., Scene]) -> None:
    distances = {}
    for mode, simulator in _both(make_block_scene(1, shape="cylinder", motion="upright", friction=0.3)).items():
        _launch(simulator, [1.0, 0.0, 0.0, 0.0, 0.0, 10.0])
        simulator.step(72)
        distances[mode] = simulator.object_positions()[0, 0]
    assert distances["footprint"] == pytest.approx(distances["geometry"], rel=0.01)


def _object_contacts(simulator: MujocoSimulator) -> list[tuple[str, str, float, tuple[float, ...]]]:
    model, data = simulator.model, simulator.data
    found = []
    for contact in data.contact[: data.ncon]:
        names = sorted(
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or "" for geom in (contact.geom1, contact.geom2)
        )
        if "ground" in names:
            continue
        normal = tuple(np.round(np.abs(contact.frame[:3]), 12))
        found.append((names[0], names[1], round(float(contact.dist), 12), normal))
    return sorted(found)


def test_lateral_contacts_are_the_objects_own_shapes() -> None:
    # Random layouts of touching cylinders and the pusher: every contact that is not with the
    # ground has the same pair, distance and normal in both models.
    task = PushingTask()
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(20):
        trajectory = task.sample_trajectory(rng, 4)
        frame = trajectory.initial
        pos = frame.object_pos.copy()
        # Pack the objects into a tight cluster so that they touch each other.
        pos[:, 0] = pos[0, 0] + 0.098 * np.arange(4) + rng.uniform(-0.003, 0.003, 4)
        pos[:, 1] = pos[0, 1] + rng.uniform(-0.01, 0.01, 4)
        robot_q = frame.robot_q.copy()
        robot_q[:2] = [pos[1, 0], pos[:, 1].min() - 0.149]
        packed = dataclasses.replace(frame, object_pos=pos, robot_q=robot_q)
        contacts = {}
        for mode in ("geometry", "footprint"):
            scene = get_task("pushing", {"ground_contact": mode}).build_scene(4, trajectory.friction)
            simulator = MujocoSimulator(scene)
            simulator.reset(packed)
            contacts[mode] = _object_contacts(simulator)
        assert contacts["footprint"] == contacts["geometry"]
        checked += len(contacts["geometry"])
    assert checked > 20


def test_scripted_pushing_is_stable_with_footprints() -> None:
    # Over whole scripted roll-outs: objects stay on the ground and nothing explodes. (The two
    # models' roll-outs drift apart after collisions, as any two contact models do; their labels
    # and AP are compared on whole datasets in docs/results/performance.md.)
    for mode in ("geometry", "footprint"):
        task = get_task("pushing", {"ground_contact": mode})
        rng = np.random.default_rng(7)
        trajectory = task.sample_trajectory(rng, 5)
        simulator = MujocoSimulator(task.build_scene(5, trajectory.friction, trajectory.drive))
        simulator.reset(trajectory.initial)
        rest = task.config.ground_z + task.config.object_half_height
        dt = simulator.timestep
        for step in range(round(task.config.duration / dt)):
            command_robot(task, simulator, trajectory.drive, step * dt, np.random.default_rng(step))
            simulator.step(1)
            z = simulator.object_positions()[:, 2]
            # Soft contacts: a hit of the pusher may press one in or lift it by a millimetre or so.
            assert np.all(z - rest > -3e-3), (mode, step, z)
            assert np.all(z - rest < 5e-3), (mode, step, z)
            velocity = simulator.object_velocities()
            assert np.abs(velocity[:, :3]).max() < 3.0, (mode, step)
            assert np.abs(velocity[:, 3:]).max() < 50.0, (mode, step)
