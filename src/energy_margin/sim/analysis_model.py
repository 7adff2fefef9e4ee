"""The analysis model: a copy of a compiled model whose contacts are only those that can move an object.

The energy margin asks how the objects move. A user's model also computes contacts that cannot
change that: the robot against itself (links, fingers, finger pads), and, when the robot is held
still during the propagation, the robot against the world. :func:`keep_object_contacts` drops
them from a model (edited in place: give it the analysis's own copy) by rewriting the geoms'
``contype`` and ``conaffinity`` bit masks, so that MuJoCo's collision filter never hands those
pairs to the narrow phase:

* a pair with an object geom collides exactly as before (its masks test as the original ones);
* a pair of two geoms on moving non-object bodies (the robot, mocap bodies and what is welded to
  them) never collides;
* a pair of a moving non-object geom and a static one (welded to the world) collides as before,
  unless ``robot_still`` (then it never collides: a robot held still by its armature is not moved
  measurably by it anyway);
* explicit ``<pair>`` contacts and ``<exclude>`` elements are not touched.

**Exact where it can be.** The contacts MuJoCo finds are those of the original model less the
dropped pairs, in the same order. When no dropped pair touches during a propagation, every state is
the same to the last bit as in the original model (tested); a dropped robot self-contact changes the
robot's own motion only, and through it the objects only where the robot then touches them.

The rewrite needs two free mask bits for every bit the model uses: with more than 10 bits in use
the model is left as it is (:attr:`PrunedContacts.applied` is ``False`` and ``reason`` says why).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

__all__ = ["MASK_BITS", "PrunedContacts", "keep_object_contacts", "moving_geoms"]

#: Bits of MuJoCo's ``contype`` / ``conaffinity`` masks.
MASK_BITS = 32


@dataclass(frozen=True)
class PrunedContacts:
    """What :func:`keep_object_contacts` did to a model.

    Attributes:
        applied: whether the masks were rewritten.
        object_geoms: colliding geoms of the objects.
        robot_geoms: colliding geoms of moving non-object bodies (their pairs among each other
            are dropped).
        static_geoms: colliding geoms welded to the world.
        robot_still: whether robot-world pairs were dropped too.
        reason: why the model was left as it is (``""`` when applied).

    """

    applied: bool
    object_geoms: int
    robot_geoms: int
    static_geoms: int
    robot_still: bool
    reason: str = ""


def moving_geoms(model: object) -> np.ndarray:
    """Whether each geom is on a body that moves (not welded to the world), shape (ngeom,), bool."""
    weld = np.asarray(model.body_weldid)[np.asarray(model.geom_bodyid)]  # type: ignore[attr-defined]
    return weld != 0


def _spread(masks: np.ndarray, used: list[int], free: list[int]) -> np.ndarray:
    """``masks`` with every used bit moved to its free partner, int32."""
    moved = np.zeros_like(masks)
    for low, high in zip(used, free, strict=False):
        moved |= ((masks >> low) & 1) << high
    return moved


def keep_object_contacts(model: object, geom_is_object: np.ndarray, *, robot_still: bool = False) -> PrunedContacts:
    """Drop the contact pairs that cannot move an object from ``model`` (edited in place).

    Args:
        model: a compiled ``mujoco.MjModel``, the analysis's own copy.
        geom_is_object: whether each geom belongs to an object, shape (ngeom,), bool.
        robot_still: the robot is held still during the propagation: drop its pairs with the
            world too.

    Returns:
        What was kept and dropped. Apply it once per model: a second call would treat the
        rewritten masks as the original ones.

    """
    contype = np.asarray(model.geom_contype).astype(np.int64)  # type: ignore[attr-defined]
    conaffinity = np.asarray(model.geom_conaffinity).astype(np.int64)  # type: ignore[attr-defined]
    colliding = (contype | conaffinity) != 0
    is_object = np.asarray(geom_is_object, dtype=bool)
    moving = moving_geoms(model)
    robot = colliding & moving & ~is_object
    static = colliding & ~moving & ~is_object
    report = functools.partial(
        PrunedContacts,
        object_geoms=int((colliding & is_object).sum()),
        robot_geoms=int(robot.sum()),
        static_geoms=int(static.sum()),
        robot_still=robot_still,
    )
    if not robot.any():
        return report(applied=False, reason="no moving non-object geom collides")
    in_use = int(np.bitwise_or.reduce(contype | conaffinity))
    used = [bit for bit in range(MASK_BITS) if in_use >> bit & 1]
    free = [bit for bit in range(MASK_BITS) if not in_use >> bit & 1]
    if len(free) < 2 * len(used):
        reason = (
            f"the model uses {len(used)} of the {MASK_BITS} contact mask bits; "
            f"at most {MASK_BITS // 3} leave room for the rewrite"
        )
        return report(applied=False, reason=reason)
    offer, accept = free[: len(used)], free[len(used) : 2 * len(used)]
    # Three copies of the used bits: the original ones, "offer" and "accept". A robot geom offers
    # contacts on the offer copy and accepts them on the accept copy only, so two robot geoms never
    # match; objects also accept on the offer copy and offer on the accept copy, so an object pair
    # with the robot tests as the original masks (each term is an image of an original one) and an
    # object pair with anything else as before. Static geoms do the same as objects for a moving
    # robot, and keep the original bits only for a still one.
    new_contype, new_conaffinity = contype.copy(), conaffinity.copy()
    answer = is_object | (static if not robot_still else np.zeros_like(static))
    new_contype[answer] |= _spread(contype[answer], used, accept)
    new_conaffinity[answer] |= _spread(conaffinity[answer], used, offer)
    new_contype[robot] = _spread(contype[robot], used, offer)
    new_conaffinity[robot] = _spread(conaffinity[robot], used, accept)
    model.geom_contype[:] = new_contype.astype(np.int32)  # type: ignore[attr-defined]
    model.geom_conaffinity[:] = new_conaffinity.astype(np.int32)  # type: ignore[attr-defined]
    return report(applied=True)
