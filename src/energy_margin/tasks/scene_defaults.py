"""Perturbation settings a scene file leaves out: fixed defaults, or derived from the scene.

A key of ``[perturbation]`` left out takes the fixed default (:data:`DEFAULTS`: 2 m/s² in x and y,
20 rad/s² about z, 0.1 s, λ = 5 1/J): pushes in the plane of a horizontal surface and a torque about
its normal, for objects resting on it, as every example sets by hand. The plane is the one normal to
gravity, so a model whose gravity has an x or y component gets no default bounds: it must give both
(:func:`check_planar_gravity`; without gravity, MuJoCo's up axis z is taken). With ``derive = true``
a key left out is derived from the scene instead, by rules
anchored on the paper's planar pushing task (10 cylinders of 0.2 kg, radius 5 cm, friction 0.1–0.3,
2 s roll-outs analysed at 10 frames; 2 m/s² in x and y, 0.667 rad/s² about z, 0.1 s, λ = 5 1/J):

* **propagation length** ``max_duration``: 0.45 of the time between frames, the frames being the
  10 that ``generate`` takes by default over the motion's duration (2 s → 0.1 s);
* **linear bound** per world axis: μ̄ g, the deceleration the objects' sliding friction gives them
  (μ̄ the middle of ``randomize.friction``, else the mean sliding friction of the objects' geoms;
  the paper's μ̄ = 0.2 → 1.96 m/s²);
* **angular bound** per axis: the linear bound over the object's radius of gyration about that axis,
  times the paper's ratio 0.0118 (its cylinders: 0.667 rad/s² for 2 m/s² and a radius of gyration
  of 3.5 cm);
* **λ**: 0.080 J (the paper's λ times the energy of one full-bound perturbation of its cylinders,
  two linear axes and rotation about z) divided by the energy of one full-bound perturbation of
  this scene's objects, W = mean over objects of Σ_axes (m a² + I α²) τ²: scaling every mass, or
  the bounds, leaves λ W as it was.

A scene file's free objects are perturbed along all three axes, so the rule applied to the paper's
cylinders as free bodies gives λ = 3.46 (not 5): W counts the vertical axis too. Measured on seven
example robots (docs/results/generality.md), the derived settings are level with the file's own on two and
behind on the others, which is why they are not the default.

``energy-margin scene`` prints each derived value with the reason (:attr:`PerturbationSettings.derived`).
:func:`object_armature` is what a scene's wrench limits add to each object's mass and inertia.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from energy_margin.sim.mujoco_index import ModelIndex, object_geoms, object_inertials
from energy_margin.tasks.scene_spec import SceneSpec

__all__ = [
    "ANGULAR_RATIO",
    "DEFAULTS",
    "FRAMES",
    "GRAVITY",
    "LAMBDA_ENERGY",
    "PROPAGATION_PER_FRAME",
    "PerturbationSettings",
    "check_planar_gravity",
    "object_armature",
    "resolve_perturbation",
]

GRAVITY = 9.81  # m/s^2
#: What a key left out takes without ``derive = true``: the bounds act in the world x-y plane (normal
#: to gravity along z) with a torque about z, as on objects resting on a horizontal surface.
DEFAULTS: dict[str, Any] = {
    "linear_acceleration": (2.0, 2.0, 0.0),
    "angular_acceleration": (0.0, 0.0, 20.0),
    "max_duration": 0.1,
    "lambda": 5.0,
}
#: Frames per roll-out that the propagation length is derived for (``generate``'s default).
FRAMES = 10
#: Propagation length as a share of the time between frames (the paper: 0.1 s of 2 s / 9).
PROPAGATION_PER_FRAME = 0.45
#: Angular bound per (linear bound / radius of gyration) (the paper: 0.667 / (2.0 / 0.0354)).
ANGULAR_RATIO = 0.667 / (2.0 / (0.05 / np.sqrt(2.0)))
#: The paper's λ times the energy of one full-bound perturbation of its cylinders, J (dimensionless λ W).
LAMBDA_ENERGY = 5.0 * (0.2 * (2.0**2 + 2.0**2) + 0.5 * 0.2 * 0.05**2 * 0.667**2) * 0.1**2


@dataclass(frozen=True)
class PerturbationSettings:
    """The perturbation of a scene: the file's values, and derived ones where it has none.

    Attributes:
        linear_acceleration: force bound per world axis divided by mass, (3,), m/s^2.
        angular_acceleration: torque bound per axis divided by inertia, (3,), rad/s^2.
        max_duration: longest propagation, s.
        likelihood_lambda: softmax inverse temperature λ, 1/J.
        derived: for each scene-file key that was derived (``"lambda"``, ``"max_duration"``, ...),
            the reason in words; empty when the file sets all four.

    """

    linear_acceleration: tuple[float, float, float]
    angular_acceleration: tuple[float, float, float]
    max_duration: float
    likelihood_lambda: float
    derived: dict[str, str] = field(default_factory=dict)


def _friction(spec: SceneSpec, model: mujoco.MjModel, bodies: np.ndarray) -> tuple[float, str]:
    if spec.friction_range is not None:
        low, high = spec.friction_range
        return 0.5 * (low + high), f"the middle of randomize.friction [{low:g}, {high:g}]"
    geoms = np.sort(np.concatenate(object_geoms(model, bodies)))
    value = float(np.mean(model.geom_friction[geoms, 0]))
    return value, "the objects' geoms' mean sliding friction"


def _three(values: Any) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def check_planar_gravity(spec: SceneSpec, model: mujoco.MjModel) -> None:
    """Refuse the planar default bounds on a model whose gravity is not along z.

    The default bounds (:data:`DEFAULTS`) act in the world x-y plane with a torque about z, the
    plane of a surface normal to gravity. Per-axis bounds cannot describe a tilted plane, so a model
    whose gravity has an x or y component must give both bounds. Without gravity, z (MuJoCo's up
    axis) is taken.

    Raises:
        EnergyMarginError: the file leaves a bound out and the gravity is not along z (one line).
    """
    missing = [
        key
        for key, value in (
            ("linear_acceleration", spec.linear_acceleration),
            ("angular_acceleration", spec.angular_acceleration),
        )
        if value is None
    ]
    gravity = np.asarray(model.opt.gravity, dtype=float)
    if not missing or float(np.hypot(gravity[0], gravity[1])) <= 1e-9 * float(np.linalg.norm(gravity)):
        return
    raise spec.error(
        f"perturbation.{missing[0]}" if len(missing) == 1 else "perturbation",
        f"the default bounds act in the world x-y plane with a torque about z, but {spec.mjcf.name}'s gravity "
        f"({', '.join(f'{g:g}' for g in gravity)}) m/s^2 is not along z: give "
        + " and ".join(f"perturbation.{key}" for key in missing),
    )


def resolve_perturbation(spec: SceneSpec, model: mujoco.MjModel, bodies: np.ndarray) -> PerturbationSettings:
    """The scene's perturbation: the file's keys, and defaults or derived values for the others.

    A key left out takes :data:`DEFAULTS`, or with ``derive = true`` the rule of this module.

    Args:
        spec: the validated scene file (``None`` for a perturbation key it leaves out).
        model: the compiled model (its object masses, inertias, friction and gravity).
        bodies: body id of each object, shape (n_objects,).

    Raises:
        EnergyMarginError: a bound left out without ``derive = true`` on a model whose gravity is
            not along z (:func:`check_planar_gravity`).

    """
    if not spec.derive_perturbation:
        check_planar_gravity(spec, model)
        return PerturbationSettings(
            linear_acceleration=_three(spec.linear_acceleration or DEFAULTS["linear_acceleration"]),
            angular_acceleration=_three(spec.angular_acceleration or DEFAULTS["angular_acceleration"]),
            max_duration=float(spec.max_duration if spec.max_duration is not None else DEFAULTS["max_duration"]),
            likelihood_lambda=float(
                spec.likelihood_lambda if spec.likelihood_lambda is not None else DEFAULTS["lambda"]
            ),
        )
    derived: dict[str, str] = {}
    mass_scale = 1.0 if spec.mass_scale is None else 0.5 * sum(spec.mass_scale)
    base_mass, base_inertia = object_inertials(model, bodies)
    mass = base_mass * mass_scale
    inertia = base_inertia * mass_scale
    spacing = spec.motion.duration / (FRAMES - 1)
    if spec.max_duration is None:
        max_duration = PROPAGATION_PER_FRAME * spacing
        derived["max_duration"] = (
            f"{PROPAGATION_PER_FRAME:g} of the {spacing:.3g} s between {FRAMES} frames over the motion's "
            f"{spec.motion.duration:g} s"
        )
    else:
        max_duration = spec.max_duration
    if spec.linear_acceleration is None:
        friction, source = _friction(spec, model, bodies)
        bound = friction * GRAVITY
        linear: tuple[float, ...] = (bound, bound, bound)
        derived["linear_acceleration"] = f"mu g per axis, mu = {friction:.3g} ({source})"
    else:
        linear = spec.linear_acceleration
    if spec.angular_acceleration is None:
        gyration = np.sqrt(np.mean(inertia, axis=0) / np.mean(mass))
        angular_array = ANGULAR_RATIO * np.asarray(linear) / np.maximum(gyration, 1e-9)
        angular: tuple[float, ...] = (float(angular_array[0]), float(angular_array[1]), float(angular_array[2]))
        derived["angular_acceleration"] = (
            f"{ANGULAR_RATIO:.3g} x the linear bound over the radius of gyration "
            f"({', '.join(f'{value * 100:.2g}' for value in gyration)} cm)"
        )
    else:
        angular = spec.angular_acceleration
    if spec.likelihood_lambda is None:
        energy = float(
            np.mean(mass * np.sum(np.square(linear)) + inertia @ np.square(np.asarray(angular))) * max_duration**2
        )
        likelihood_lambda = LAMBDA_ENERGY / max(energy, 1e-12)
        derived["lambda"] = (
            f"{LAMBDA_ENERGY:.3g} J over the energy of one full-bound perturbation, {energy:.3g} J "
            f"(mean object mass {np.mean(mass) * 1000:.3g} g)"
        )
    else:
        likelihood_lambda = spec.likelihood_lambda
    return PerturbationSettings(
        linear_acceleration=(float(linear[0]), float(linear[1]), float(linear[2])),
        angular_acceleration=(float(angular[0]), float(angular[1]), float(angular[2])),
        max_duration=float(max_duration),
        likelihood_lambda=float(likelihood_lambda),
        derived=derived,
    )


def object_armature(model: mujoco.MjModel, index: ModelIndex, n_objects: int) -> tuple[np.ndarray, np.ndarray]:
    """Armature of each object's joints along x, y, z (n, 3), kg, and about them (n, 3), kg m^2.

    Args:
        model: the scene's compiled model.
        index: the objects' coordinates in it.
        n_objects: number of objects.

    """
    armature = model.dof_armature
    n = n_objects
    if not index.upright:
        return armature[index.linvel_index], armature[index.angvel_index]
    mask = index.axis_mask if index.axis_mask is not None else np.ones((n, 4), dtype=bool)
    linear = np.where(mask[:, :3], armature[index.linvel_index], 0.0)
    angular = np.zeros((n, 3))
    angular[:, 2] = np.where(mask[:, 3], armature[index.yaw_rate_index], 0.0)
    return linear, angular
