"""The analysis model: contact pairs that cannot move an object are dropped, the rest are exact."""

from __future__ import annotations

import copy
import types

import mujoco
import numpy as np
import pytest

from energy_margin.sim.analysis_model import keep_object_contacts
from tiny_scene import sweeping_arm


def _arm(height: float = 0.05) -> tuple[mujoco.MjModel, np.ndarray]:
    model = mujoco.MjModel.from_xml_string(sweeping_arm(height=height))
    box = model.body("box").id
    return model, model.geom_bodyid == box


def _run(model: mujoco.MjModel, ctrl: list[float], steps: int) -> tuple[np.ndarray, list[int], set[tuple[str, str]]]:
    """The box's pose after ``steps`` steps, the contact count of each step and the body pairs in contact."""
    data = mujoco.MjData(model)
    data.ctrl[:] = ctrl
    counts, pairs = [], set()
    for _ in range(steps):
        mujoco.mj_step(model, data)
        counts.append(int(data.ncon))
        for contact in data.contact:
            names = sorted(model.body(int(model.geom_bodyid[g])).name for g in (contact.geom1, contact.geom2))
            pairs.add((names[0], names[1]))
    box = model.body("box").id
    return np.concatenate([data.xpos[box], data.xquat[box]]), counts, pairs


def test_box_states_are_bit_identical_when_no_dropped_pair_touches() -> None:
    full, is_object = _arm()
    pruned = copy.copy(full)
    report = keep_object_contacts(pruned, is_object)
    assert report.applied and report.object_geoms == 1 and report.robot_geoms == 3 and report.static_geoms == 1
    # Fingers held open: the link sweeps into the box and pushes it.
    before, counts_full, pairs = _run(full, [0.5, 0.02, -0.02], 400)
    after, counts_pruned, _ = _run(pruned, [0.5, 0.02, -0.02], 400)
    assert ("base", "box") in pairs and ("box", "world") in pairs  # the arm did push the box
    assert not np.allclose(before[:2], [0.3, 0.12])
    np.testing.assert_array_equal(before, after)
    assert counts_full == counts_pruned


def test_robot_self_contact_is_dropped_and_object_contacts_kept() -> None:
    full, is_object = _arm()
    pruned = copy.copy(full)
    keep_object_contacts(pruned, is_object)
    # Fingers closed onto each other, the arm still.
    _, _, pairs_full = _run(full, [0.0, -0.05, 0.05], 200)
    _, _, pairs_pruned = _run(pruned, [0.0, -0.05, 0.05], 200)
    assert ("left", "right") in pairs_full
    assert ("left", "right") not in pairs_pruned
    assert ("box", "world") in pairs_pruned


def test_still_robot_drops_its_pairs_with_the_world() -> None:
    full, is_object = _arm(height=0.02)  # the link lies on the ground
    moving, still = copy.copy(full), copy.copy(full)
    keep_object_contacts(moving, is_object, robot_still=False)
    report = keep_object_contacts(still, is_object, robot_still=True)
    assert report.robot_still
    assert ("base", "world") in _run(full, [0.0, 0.0, 0.0], 50)[2]
    assert ("base", "world") in _run(moving, [0.0, 0.0, 0.0], 50)[2]
    assert ("base", "world") not in _run(still, [0.0, 0.0, 0.0], 50)[2]
    assert ("box", "world") in _run(still, [0.0, 0.0, 0.0], 50)[2]


@pytest.mark.parametrize("seed", range(4))
def test_every_pair_collides_as_before_unless_dropped(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(50):
        n = 10
        bits = rng.choice(32, size=int(rng.integers(1, 11)), replace=False)
        contype, conaffinity = (
            np.array([sum(1 << int(b) for b in bits if rng.random() < 0.4) for _ in range(n)]).astype(np.int32)
            for _ in range(2)
        )
        weld = rng.choice([0, 1, 2], size=n)
        model = types.SimpleNamespace(
            geom_contype=contype.copy(), geom_conaffinity=conaffinity.copy(), geom_bodyid=np.arange(n), body_weldid=weld
        )
        is_object, still = rng.random(n) < 0.3, bool(rng.random() < 0.5)
        robot = (weld > 0) & ~is_object & ((contype | conaffinity) != 0)
        assert keep_object_contacts(model, is_object, robot_still=still).applied == bool(robot.any())
        kind = np.where(is_object, "object", np.where(weld == 0, "static", "robot"))
        for a in range(n):
            for b in range(n):
                before = bool((contype[a] & conaffinity[b]) | (contype[b] & conaffinity[a]))
                after = bool(
                    (model.geom_contype[a] & model.geom_conaffinity[b])
                    | (model.geom_contype[b] & model.geom_conaffinity[a])
                )
                pair = {kind[a], kind[b]}
                if pair == {"static"}:
                    continue  # MuJoCo never tests two static geoms
                dropped = pair == {"robot"} or (still and pair == {"robot", "static"})
                assert after == (before and not dropped), (kind[a], kind[b], still)


def test_a_model_with_too_many_mask_bits_is_left_as_it_is() -> None:
    n = 4
    model = types.SimpleNamespace(
        geom_contype=np.array([(1 << 11) - 1] * n, dtype=np.int32),
        geom_conaffinity=np.array([(1 << 11) - 1] * n, dtype=np.int32),
        geom_bodyid=np.arange(n),
        body_weldid=np.array([0, 1, 2, 3]),
    )
    report = keep_object_contacts(model, np.array([False, True, False, False]))
    assert not report.applied and "11 of the 32" in report.reason
    assert (model.geom_contype == (1 << 11) - 1).all()
