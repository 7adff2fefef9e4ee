"""The designs of a sweep: the grid of task configurations over listed parameter values.

A design is one setting of a task's configuration. :func:`design_grid` makes the Cartesian
product of the swept values (each parameter read by
:func:`~energy_margin.design.params.parse_param`), each point a :class:`Design` with the task
configuration overrides it stands for (a parameter is a configuration field, or an alias the task
declares (``Task.design_aliases``) that sets one), and checks every design's configuration before
anything runs.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from energy_margin.design.params import is_range
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks import Task, available_tasks, get_task
from energy_margin.tasks.protocols import DesignSpace

__all__ = [
    "Design",
    "config_fields",
    "design_grid",
    "design_label",
]


@dataclass(frozen=True)
class Design:
    """One point of the grid.

    Attributes:
        values: the swept parameters' values, in the order of the parameters.
        overrides: the task configuration overrides of this design (fixed settings included).
        slug: the design's directory name under ``DIR/designs``.

    """

    values: dict[str, Any]
    overrides: dict[str, Any]
    slug: str

    @property
    def label(self) -> str:
        """The design as people read it, e.g. ``scoop_angle=1.31, open_gap=0.09``."""
        return design_label(self.values)


def config_fields(task: DesignSpace) -> dict[str, Any]:
    """Every configuration field of ``task`` with its value."""
    return {field.name: getattr(task.config, field.name) for field in dataclasses.fields(task.config)}


def _design_names(task_name: str) -> set[str] | None:
    """Every parameter name a sweep of ``task_name`` accepts; ``None`` when its default cannot be built."""
    try:
        task = get_task(task_name)
    except EnergyMarginError:
        return None
    return set(config_fields(task)) | {alias.name for alias in task.design_aliases()}


def _unknown_parameter(task: Task, name: str, known: set[str]) -> InvalidParameterError:
    # Only to word the error: which other registered task has this setting.
    owners = [other for other in available_tasks() if other != task.name and name in (_design_names(other) or set())]
    if owners:
        return InvalidParameterError(
            "params", f"{name} is a setting of task {owners[0]!r}, not of {task.name!r} (sweep task {owners[0]})"
        )
    aliases = [alias.name for alias in task.design_aliases()]
    hint = f"{', '.join(aliases)} or a {task.name} setting" if aliases else f"a {task.name} setting"
    return InvalidParameterError(
        "params",
        f"{name}: unknown {task.name} parameter; sweepable: {hint} ({', '.join(sorted(known - set(aliases)))})",
    )


def design_grid(task: Task, params: Sequence[tuple[str, Any]], *, fixed: dict[str, Any] | None = None) -> list[Design]:
    """Every design of the Cartesian product of ``params``, validated against the task's configuration.

    Args:
        task: the resolved task (``fixed`` is applied to it; each design is :meth:`Task.configured`
            from it).
        params: ``(name, values)`` per swept parameter: a configuration field or an alias of
            :meth:`~energy_margin.tasks.base.Task.design_aliases`.
        fixed: configuration overrides shared by every design (``--set``), part of every design's
            ``overrides``.

    Raises:
        InvalidParameterError: (``params``) no parameter, an unknown one, a parameter of another
            task, one given twice or also fixed, a range instead of values.
        EnergyMarginError: a design whose configuration is invalid (named).

    """
    fixed = dict(fixed or {})
    task = task.configured(fixed)
    fields = config_fields(task)
    aliases = {alias.name: alias for alias in task.design_aliases()}
    _check_params(task, params, fixed, set(fields) | set(aliases), aliases)
    designs: list[Design] = []
    slugs: dict[str, str] = {}
    for combination in itertools.product(*(values for _, values in params)):
        chosen = {name: value for (name, _), value in zip(params, combination, strict=True)}
        label = design_label(chosen)
        overrides = dict(fixed)
        for name, value in chosen.items():
            if name in aliases:
                alias = aliases[name]
                try:
                    overrides[alias.field] = alias.to_field(value, fields[alias.field])
                except ValueError as error:
                    raise EnergyMarginError(f"design {label}: {error}") from None
            else:
                overrides[name] = value
        try:
            task.configured(overrides)
        except EnergyMarginError as error:
            raise EnergyMarginError(f"design {label}: {error}") from None
        slug = "__".join(f"{name}-{_token(value)}" for name, value in chosen.items())
        if slug in slugs:
            raise EnergyMarginError(f"designs {slugs[slug]} and {label} share the directory name {slug}")
        slugs[slug] = label
        designs.append(Design(values=chosen, overrides=overrides, slug=slug))
    return designs


def _check_params(
    task: Task, params: Sequence[tuple[str, Any]], fixed: dict[str, Any], known: set[str], aliases: dict[str, Any]
) -> None:
    """Refuse no parameter, an unknown one, one given twice or also fixed, a range instead of values."""
    if not params:
        raise InvalidParameterError("params", "must hold at least one parameter NAME=A,B,C")
    targets: dict[str, str] = {}
    for name, values in params:
        if name not in known:
            raise _unknown_parameter(task, name, known)
        field = aliases[name].field if name in aliases else name
        if field in targets:
            raise InvalidParameterError("params", f"{name} sets {field}, as {targets[field]} does")
        if field in fixed:
            raise InvalidParameterError("params", f"{name} sets {field}, which is fixed for every design")
        if is_range(values):
            raise InvalidParameterError(
                "params", f"{name}: a sweep lists its values NAME=A,B,C; a range LOW:HIGH is searched by design"
            )
        if not values:
            raise InvalidParameterError("params", f"{name}: no values given")
        targets[field] = name


def design_label(values: dict[str, Any]) -> str:
    """Design values as people read them, e.g. ``scoop_angle=1.31, open_gap=0.09``."""
    return ", ".join(f"{name}={json.dumps(value)}" for name, value in values.items())


def _token(value: Any) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", json.dumps(value)).strip("_") or "_"
