"""The space a design search explores: parameters ``NAME=LOW:HIGH | NAME=A,B,C``, resolved against a task.

A design search varies some of a task's settings (configuration fields, or the aliases a task
declares, :meth:`~energy_margin.tasks.base.Task.design_aliases`) over a box of numeric ranges and
sets of categorical values, each axis a :class:`~energy_margin.tasks.base.DesignParameter`. The
axes come from the command line (:func:`~energy_margin.design.params.parse_param`, then
:func:`resolve_space`) or, without any, from the task's documented tool family
(:meth:`~energy_margin.tasks.base.Task.design_space`).

:func:`point_design` turns one point of the space into a :class:`~energy_margin.design.grid.Design`
(the configuration overrides it stands for, checked by the task's configuration, as ``sweep``'s
grid does); :func:`check_models` compiles the models of the space's corners and categorical values
before a search starts, so a design whose MuJoCo model does not compile is refused in one line
naming it; :func:`even_grid` is the grid of at most N designs spread evenly over the space (the
``grid`` optimiser, and the equal-cost grid a search is compared with).
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from energy_margin.data.generate import trajectory_rng
from energy_margin.design.grid import Design, config_fields, design_grid
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks import DesignParameter, Task, available_tasks, get_task
from energy_margin.tasks.protocols import DesignSpace

__all__ = [
    "DIGITS",
    "MAX_CORNERS",
    "axis_values",
    "check_models",
    "compile_design",
    "default_design",
    "even_grid",
    "grid_counts",
    "known_names",
    "parameter_dict",
    "point_design",
    "resolve_space",
    "round_value",
]

#: Significant digits of a numeric design value (what is simulated, written and compared on resume).
DIGITS = 6
#: The most corner combinations :func:`check_models` compiles; beyond it, each axis's ends alone.
MAX_CORNERS = 64


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def known_names(task: DesignSpace) -> list[str]:
    """Every design parameter of ``task``: its tool family's axes, its aliases, then its configuration fields."""
    names = [parameter.name for parameter in task.design_space()]
    names += [alias.name for alias in task.design_aliases() if alias.name not in names]
    names += [name for name in task.design_fields() if name not in names]
    return names


def resolve_space(
    task: Task,
    params: Sequence[tuple[str, tuple[float, float] | list[Any]]],
    *,
    fixed: dict[str, Any] | None = None,
) -> list[DesignParameter]:
    """The axes of a search of ``task`` (``fixed`` applied): the parsed parameters, or its tool family without any.

    A range over a field whose value is a whole number (or an axis the family declares
    ``integer``) takes whole values only. A categorical parameter the family declares accepts
    only the family's values.

    Raises:
        EnergyMarginError: an unknown parameter (listing the known ones), a parameter given twice
            or also in ``fixed``, a range of a categorical parameter or of a setting that
            is not a number, a value outside the family's, or no axes at all.

    """
    fixed = dict(fixed or {})
    task = task.configured(fixed)
    family = {parameter.name: parameter for parameter in task.design_space()}
    if not params:
        if not family:
            raise InvalidParameterError(
                "params",
                f"must give the axes, NAME=LOW:HIGH or NAME=A,B,C: {task.label} declares no tool family "
                f"(Task.design_space; known: {', '.join(known_names(task))})",
            )
        return list(family.values())
    fields = config_fields(task)
    aliases = {alias.name: alias for alias in task.design_aliases()}
    known = known_names(task)
    targets: dict[str, str] = {}
    space: list[DesignParameter] = []
    for name, spec in params:
        if name not in known:
            raise _unknown(task, name, known)
        field = aliases[name].field if name in aliases else name
        if field in targets:
            what = "is given twice" if targets[field] == name else f"sets {field}, as {targets[field]} does"
            raise InvalidParameterError("params", f"{name} {what}")
        if field in fixed:
            raise InvalidParameterError("params", f"{name} sets {field}, which is fixed for every design")
        targets[field] = name
        declared = family.get(name)
        doc = declared.doc if declared is not None else (aliases[name].doc if name in aliases else f"{name} setting")
        if isinstance(spec, tuple):
            integer = declared.integer if declared is not None else isinstance(fields.get(name), int)
            _check_range(task, name, declared, is_field=name not in aliases, value=fields.get(name))
            space.append(_range_axis(name, doc, spec, integer=integer))
        else:
            _check_values(task, name, declared, spec)
            space.append(DesignParameter(name, doc, choices=tuple(spec)))
    return space


def _check_range(task: Task, name: str, declared: DesignParameter | None, *, is_field: bool, value: Any) -> None:
    """Refuse a range over a categorical axis of the family, or over a setting that is not a number."""
    if declared is not None and declared.choices is not None:
        raise InvalidParameterError(
            "params",
            f"{name} is categorical in the {task.name} family "
            f"({', '.join(json.dumps(c) for c in declared.choices)}); give NAME=A,B,...",
        )
    if is_field and not _is_number(value):
        raise InvalidParameterError(
            "params",
            f"{name}: {task.name}'s {name} is not a number ({json.dumps(value)}); give its values as NAME=A,B,...",
        )


def _range_axis(name: str, doc: str, spec: tuple[float, float], *, integer: bool) -> DesignParameter:
    """The numeric axis of a range: whole values only for an ``integer`` one (at least two)."""
    low, high = spec
    if integer:
        low, high = float(math.ceil(low)), float(math.floor(high))
        if low >= high:
            raise InvalidParameterError(
                "params", f"{name}: takes whole values and {spec[0]:g}:{spec[1]:g} holds fewer than two"
            )
    return DesignParameter(name, doc, low=low, high=high, integer=integer)


def _check_values(task: Task, name: str, declared: DesignParameter | None, values: list[Any]) -> None:
    """Refuse fewer than two values, or a value outside the family's choices."""
    if len(values) < 2:
        raise InvalidParameterError(
            "params", f"{name}: give a range LOW:HIGH or at least two values A,B (or fix its one value)"
        )
    if declared is not None and declared.choices is not None:
        outside = [value for value in values if value not in declared.choices]
        if outside:
            raise InvalidParameterError(
                "params",
                f"{name}: {json.dumps(outside[0])} is not in the {task.name} family "
                f"(choices: {', '.join(json.dumps(c) for c in declared.choices)})",
            )


def _unknown(task: Task, name: str, known: list[str]) -> InvalidParameterError:
    """An unknown parameter: the task whose setting it is, if another one's, and the known ones."""
    owners = []
    for other in available_tasks():
        if other != task.name:
            try:
                if name in known_names(get_task(other)):
                    owners.append(other)
            except EnergyMarginError:
                continue
    where = f" (a setting of task {owners[0]!r})" if owners else ""
    listed = ", ".join(known) if known else "none (a scene file declares its own in a [design] table)"
    return InvalidParameterError("params", f"{name}: unknown {task.name} design parameter{where}; known: {listed}")


def round_value(parameter: DesignParameter, value: Any) -> Any:
    """A value of ``parameter`` as designs hold it: whole, or to :data:`DIGITS` significant digits."""
    if parameter.choices is not None:
        return value
    assert parameter.low is not None and parameter.high is not None
    number = min(max(float(value), parameter.low), parameter.high)
    if parameter.integer:
        return round(number)
    return float(f"{number:.{DIGITS}g}")


def point_design(task: Task, space: Sequence[DesignParameter], values: Sequence[Any], fixed: dict[str, Any]) -> Design:
    """The design of one point (a value per axis), its configuration checked.

    Raises:
        EnergyMarginError: the configuration of the design is invalid (named).

    """
    rounded = [round_value(parameter, value) for parameter, value in zip(space, values, strict=True)]
    params = [(parameter.name, [value]) for parameter, value in zip(space, rounded, strict=True)]
    return design_grid(task, params, fixed=fixed)[0]


def default_design(task: DesignSpace, space: Sequence[DesignParameter], fixed: dict[str, Any]) -> Design:
    """The task's own design (its configuration with ``fixed``), labelled by its values on the searched axes.

    An axis that is an alias has no inverse from the configuration; it is labelled ``"default"``.
    """
    fields = config_fields(task.configured(fixed))
    values = {p.name: fields.get(p.name, "default") for p in space}
    return Design(values=values, overrides=dict(fixed), slug="default")


def compile_design(task: Task, design: Design, *, n_objects: int, seed: int, n_trajectories: int) -> None:
    """Build the simulator of the design's first trajectory (its MuJoCo model compiled).

    Raises:
        EnergyMarginError: the model does not compile: MuJoCo's message, naming the design.

    """
    variant = task.configured(design.overrides)
    try:
        trajectory = variant.sample_trajectory(trajectory_rng(seed, n_trajectories, 0), n_objects)
        variant.make_simulator(n_objects, trajectory.friction, trajectory.drive)
    except (ValueError, RuntimeError) as error:
        raise EnergyMarginError(f"the model of design {design.label} does not compile: {error}") from None


def _ends(parameter: DesignParameter) -> list[Any]:
    if parameter.choices is not None:
        return list(parameter.choices)
    return [parameter.low, parameter.high]


def _middle(parameter: DesignParameter) -> Any:
    if parameter.choices is not None:
        return parameter.choices[0]
    assert parameter.low is not None and parameter.high is not None
    return (parameter.low + parameter.high) / 2.0


def check_models(
    task: Task,
    space: Sequence[DesignParameter],
    fixed: dict[str, Any],
    *,
    n_objects: int,
    seed: int,
    n_trajectories: int,
) -> int:
    """Check the configuration and compile the model of the space's corners (every categorical value); the count.

    With more than :data:`MAX_CORNERS` corners, each axis's ends (every value of a categorical
    axis) with the other axes at their middle (first value) instead.

    Raises:
        EnergyMarginError: a design whose configuration is invalid, or whose model does not
            compile (MuJoCo's message), named.

    """
    ends = [_ends(parameter) for parameter in space]
    if math.prod(len(values) for values in ends) <= MAX_CORNERS:
        points = [list(point) for point in itertools.product(*ends)]
    else:
        middle = [_middle(parameter) for parameter in space]
        points = [[*middle[:axis], value, *middle[axis + 1 :]] for axis, values in enumerate(ends) for value in values]
    for point in points:
        design = point_design(task, space, point, fixed)
        compile_design(task, design, n_objects=n_objects, seed=seed, n_trajectories=n_trajectories)
    return len(points)


def _capacity(parameter: DesignParameter) -> float:
    if parameter.choices is not None:
        return len(parameter.choices)
    if parameter.integer:
        assert parameter.low is not None and parameter.high is not None
        return int(parameter.high - parameter.low) + 1
    return math.inf


def grid_counts(space: Sequence[DesignParameter], budget: int) -> list[int]:
    """Points per axis of the largest even grid of at most ``budget`` designs.

    Axes grow in turn, the one with the fewest points first (the first axis on a tie), while the
    product stays within ``budget``; a categorical axis holds at most its values, an integer one
    at most its whole numbers.
    """
    counts = [1] * len(space)
    while True:
        total = math.prod(counts)
        order = sorted(range(len(space)), key=lambda axis: (counts[axis], axis))
        for axis in order:
            if counts[axis] < _capacity(space[axis]) and total // counts[axis] * (counts[axis] + 1) <= budget:
                counts[axis] += 1
                break
        else:
            return counts


def axis_values(parameter: DesignParameter, count: int) -> list[Any]:
    """``count`` values spread evenly over an axis: the centres of ``count`` equal cells of a range (rounded)."""
    if parameter.choices is not None:
        size = len(parameter.choices)
        return [parameter.choices[int((index + 0.5) * size / count)] for index in range(count)]
    assert parameter.low is not None and parameter.high is not None
    if parameter.integer:
        width = parameter.high - parameter.low + 1
        numbers = [parameter.low - 0.5 + (index + 0.5) * width / count for index in range(count)]
        return [int(np.floor(number + 0.5)) for number in numbers]
    width = parameter.high - parameter.low
    return [round_value(parameter, parameter.low + (index + 0.5) * width / count) for index in range(count)]


def even_grid(space: Sequence[DesignParameter], budget: int) -> list[list[Any]]:
    """The points of the largest even grid of at most ``budget`` designs (:func:`grid_counts`), in product order."""
    counts = grid_counts(space, budget)
    return [
        list(point) for point in itertools.product(*(axis_values(p, c) for p, c in zip(space, counts, strict=True)))
    ]


def parameter_dict(parameter: DesignParameter) -> dict[str, Any]:
    """An axis as JSON (``design.json``)."""
    entry: dict[str, Any] = {"name": parameter.name, "doc": parameter.doc}
    if parameter.choices is not None:
        entry["choices"] = list(parameter.choices)
    else:
        entry.update(low=parameter.low, high=parameter.high, integer=parameter.integer)
    return entry
