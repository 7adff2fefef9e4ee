"""Incremental cost Q of one propagation (paper eq. 5-6).

Two models, selectable by name:

* ``"wrench"`` (default): the work of the random perturbation wrench itself, taken per object in
  absolute value and summed, ``Q = sum_i |F_i . dp_i + tau_i . dphi_i|``. Because the wrench is
  constant in the world frame the force term is exact; the torque term uses the rotation vector
  of the relative rotation (exact for planar rotation, first order in 3-D).
* ``"energy"``: the paper's energy balance ``Q = |dE - W_fri|`` with ``E`` the objects' kinetic
  plus potential energy and ``W_fri`` the (negative) work of friction at every contact that
  involves an object. What remains is the work of every non-friction external force: the
  perturbation and the end-effector's contact forces.

When the end-effector touches nothing and objects do not collide, ``energy`` equals
``|sum_i W_i|`` up to the engine's contact softness, and ``wrench`` equals ``sum_i |W_i|``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from energy_margin.errors import check_choice
from energy_margin.world.state import relative_rotation_vector

__all__ = [
    "COST_MODELS",
    "MIN_COST",
    "CostModel",
    "EnergyBalanceCost",
    "Propagation",
    "WrenchWorkCost",
    "make_cost_model",
    "wrench_work_per_object",
]

#: Smallest incremental cost, so every edge costs something (as the reference).
MIN_COST = 1e-9


@dataclass(frozen=True)
class Propagation:
    """What the cost models see of one propagation, or of k propagations stacked.

    The shapes below are those of one propagation; k propagations stack them on a leading axis
    (``wrenches`` (k, n_objects, 6), the energies and friction work (k,)), which is how the tree
    costs the nodes it added since it last scored (one vectorised call instead of one per node).

    Attributes:
        wrenches: applied wrenches, shape (n_objects, 6), N and N m, world frame.
        pos_before: object positions at the start, shape (n_objects, 3), m.
        pos_after: object positions at the end, shape (n_objects, 3), m.
        quat_before: orientations at the start, shape (n_objects, 4).
        quat_after: orientations at the end, shape (n_objects, 4).
        energy_before: objects' mechanical energy at the start, J.
        energy_after: objects' mechanical energy at the end, J.
        friction_work: work of friction at object contacts, J (<= 0).

    """

    wrenches: np.ndarray
    pos_before: np.ndarray
    pos_after: np.ndarray
    quat_before: np.ndarray
    quat_after: np.ndarray
    energy_before: float | np.ndarray = 0.0
    energy_after: float | np.ndarray = 0.0
    friction_work: float | np.ndarray = 0.0


class CostModel(Protocol):
    """Maps a propagation to its incremental cost Q >= MIN_COST (J)."""

    name: str
    needs_friction_work: bool

    def __call__(self, propagation: Propagation) -> float:
        """Incremental cost of one propagation, J."""
        ...

    def increments(self, propagations: Propagation) -> np.ndarray:
        """Incremental costs of k stacked propagations, shape (k,), J (the same values as calls).

        Optional: the tree calls the model once per node when a model does not define it.
        """
        ...


def wrench_work_per_object(propagation: Propagation) -> np.ndarray:
    """Work of each object's perturbation wrench, shape (n_objects,) (or (k, n_objects) stacked), J."""
    displacement = propagation.pos_after - propagation.pos_before
    rotation = relative_rotation_vector(propagation.quat_before, propagation.quat_after)
    forces, torques = propagation.wrenches[..., :3], propagation.wrenches[..., 3:]
    return np.sum(forces * displacement, axis=-1) + np.sum(torques * rotation, axis=-1)


class WrenchWorkCost:
    """``Q = sum_i |W_i|``: work of the perturbation wrench, absolute per object."""

    name = "wrench"
    needs_friction_work = False

    def __call__(self, propagation: Propagation) -> float:
        """Incremental cost, J."""
        return float(self.increments(propagation))

    def increments(self, propagations: Propagation) -> np.ndarray:
        """Incremental costs of stacked propagations, shape (k,), J."""
        return np.maximum(np.sum(np.abs(wrench_work_per_object(propagations)), axis=-1), MIN_COST)


class EnergyBalanceCost:
    """``Q = |E' - E - W_fri|``: external non-friction work on the objects (paper eq. 6)."""

    name = "energy"
    needs_friction_work = True

    def __call__(self, propagation: Propagation) -> float:
        """Incremental cost, J."""
        return float(self.increments(propagation))

    def increments(self, propagations: Propagation) -> np.ndarray:
        """Incremental costs of stacked propagations, shape (k,), J."""
        external = (
            np.asarray(propagations.energy_after)
            - np.asarray(propagations.energy_before)
            - np.asarray(propagations.friction_work)
        )
        return np.maximum(np.abs(external), MIN_COST)


COST_MODELS: dict[str, type[WrenchWorkCost] | type[EnergyBalanceCost]] = {
    "wrench": WrenchWorkCost,
    "energy": EnergyBalanceCost,
}


def make_cost_model(name: str) -> CostModel:
    """The cost model called ``name`` (``"wrench"`` or ``"energy"``)."""
    return COST_MODELS[check_choice("cost", name, COST_MODELS)]()
