"""A scene file's ``[design]`` parameters set on the model's ``mujoco.MjSpec`` before it is compiled.

:func:`apply_design` checks each parameter's element, attribute and index against the model and
sets its value; a body whose inertial a parameter sets is first made explicit, as compiled.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np

from energy_margin.errors import InvalidParameterError
from energy_margin.tasks.scene_spec import DesignEntry, SceneSpec

__all__ = ["apply_design"]


def _one_line(error: Exception) -> str:
    return " ".join(str(error).split())


_SPEC_ELEMENTS = {"body": "body", "geom": "geom", "site": "site", "joint": "joint", "actuator": "actuator"}


def _design_target(spec: SceneSpec, model_spec: mujoco.MjSpec, entry: DesignEntry) -> tuple[Any, float]:
    """The ``MjSpec`` element of a design parameter and the attribute's current value (checked)."""
    element = getattr(model_spec, _SPEC_ELEMENTS[entry.kind])(entry.element)
    if element is None:
        raise spec.error(f"{entry.key}.{entry.kind}", f"no {entry.kind} {entry.element!r} in {spec.mjcf.name}")
    value = getattr(element, entry.attribute, None)
    what = f"{entry.kind} {entry.element!r}"
    if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.ndim == 1 and value.size:
        if entry.index is None:
            if value.size > 1:
                raise spec.error(
                    entry.key,
                    f"{entry.attribute} of {what} holds {value.size} numbers: give index (0 to {value.size - 1})",
                )
            return element, float(value[0])
        if entry.index >= value.size:
            raise spec.error(
                f"{entry.key}.index",
                f"index {entry.index} is out of range: {entry.attribute} of {what} holds {value.size} numbers "
                f"(index 0 to {value.size - 1})",
            )
        return element, float(value[entry.index])
    if isinstance(value, float):
        if entry.index is not None:
            raise spec.error(f"{entry.key}.index", f"{entry.attribute} of {what} is one number: leave index out")
        return element, value
    if value is None and not hasattr(element, entry.attribute):
        raise spec.error(f"{entry.key}.attribute", f"{what} has no attribute {entry.attribute!r}")
    raise spec.error(
        f"{entry.key}.attribute",
        f"{entry.attribute} of {what} is not a real number or a list of them ({type(value).__name__})",
    )


#: A body's inertial attributes: MuJoCo reads them only when the body's inertial is explicit.
_INERTIAL = ("mass", "inertia", "ipos", "iquat", "fullinertia")


def _explicit_inertials(spec: SceneSpec, model_spec: mujoco.MjSpec) -> None:
    """Make the inertial of each body a design parameter sets explicit, as the compiled model has it.

    MuJoCo ignores a body's ``mass``, ``inertia`` and ``ipos`` unless its inertial is explicit (an
    ``<inertial>`` element), and otherwise derives them from its geoms. Each such body gets
    ``explicitinertial`` with the mass, principal inertia, centre of mass and axes of the model
    compiled before the design, so the parameter changes its own attribute only and its default
    (the model's own value) is the compiled one.
    """
    entries = [entry for entry in spec.design if entry.kind == "body" and entry.attribute in _INERTIAL]
    if not entries:
        return
    for entry in entries:
        if entry.attribute == "fullinertia":
            raise spec.error(
                f"{entry.key}.attribute", "fullinertia cannot be a design parameter: use inertia (principal moments)"
            )
    if model_spec.compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE:
        entry = entries[0]
        raise spec.error(
            f"{entry.key}.attribute",
            f"{entry.attribute} of body {entry.element!r} cannot be set: the model computes every body's inertial "
            'from its geoms (compiler inertiafromgeom="true")',
        )
    try:
        compiled = model_spec.copy().compile()
    except (ValueError, mujoco.FatalError) as error:
        raise spec.error("mjcf", f"{spec.mjcf.name} does not compile: {_one_line(error)}") from None
    for entry in entries:
        body = model_spec.body(entry.element)
        index = mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_BODY, entry.element)
        if body is None or index < 0:
            continue  # refused by name in _design_target
        if body.explicitinertial and np.isnan(body.fullinertia[0]):
            continue  # its own <inertial>: mass, inertia, ipos and iquat are what MuJoCo uses
        body.explicitinertial = True
        body.mass = float(compiled.body_mass[index])
        body.inertia = compiled.body_inertia[index].copy()
        body.ipos = compiled.body_ipos[index].copy()
        body.iquat = compiled.body_iquat[index].copy()
        body.fullinertia[0] = np.nan


def apply_design(
    spec: SceneSpec, model_spec: mujoco.MjSpec, design: Mapping[str, Any] | None = None
) -> dict[str, float]:
    """Set every ``[design]`` parameter of ``spec`` on ``model_spec``; the values set, by name.

    A parameter takes its value in ``design``, else its ``default``, else keeps the model's own.

    Raises:
        InvalidParameterError: ``design`` names a parameter the file does not declare.
        EnergyMarginError: an element or attribute the model does not have, an index out of range,
            a value that is not a number or lies outside the parameter's range (``FILE:LINE: design.NAME``).

    """
    design = dict(design or {})
    declared = {entry.name for entry in spec.design}
    unknown = sorted(set(design) - declared)
    if unknown:
        names = ", ".join(sorted(declared)) or "none"
        raise InvalidParameterError(
            "design",
            f"names unknown scene configuration keys: {', '.join(unknown)} "
            f"(the [design] parameters of {spec.path}: {names})",
        )
    _explicit_inertials(spec, model_spec)
    values: dict[str, float] = {}
    for entry in spec.design:
        element, current = _design_target(spec, model_spec, entry)
        value = design.get(entry.name, entry.default if entry.default is not None else current)
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise spec.error(entry.key, f"{entry.name} must be a finite number, got {value!r}")
        if not entry.low <= value <= entry.high:
            given = "given" if entry.name in design else "the model's" if entry.default is None else "default"
            raise spec.error(
                entry.key, f"{entry.name} = {value:g} ({given}) lies outside its range [{entry.low:g}, {entry.high:g}]"
            )
        if entry.index is None:
            if isinstance(getattr(element, entry.attribute), float):
                setattr(element, entry.attribute, float(value))
            else:
                getattr(element, entry.attribute)[0] = float(value)
        else:
            getattr(element, entry.attribute)[entry.index] = float(value)
        values[entry.name] = float(value)
    return values
