"""Find the MuJoCo ``MjModel`` and ``MjData`` inside a user's environment, whatever stack built it.

One mechanism for every wrapper: :func:`find_mujoco` looks, breadth first, at the object given and
at what it wraps, for

* ``model`` and ``data`` that are a ``mujoco.MjModel`` and ``mujoco.MjData`` (Gymnasium's MuJoCo
  environments, gymnasium-robotics, Meta-World);
* ``sim``, robosuite's simulation (``sim.model._model`` and ``sim.data._data``), which its
  ``GymWrapper`` and its own environments hold;
* ``physics``, a dm_control ``Physics`` (``physics.model.ptr`` and ``physics.data.ptr``): dm_control
  suites and composer tasks, and environments built on them such as LeRobot's gym-aloha;

following ``unwrapped``, ``env`` and ``_env`` (Gymnasium and robosuite wrappers, gym-aloha's inner
dm_control environment). It only reads attributes; nothing is imported or changed.
"""

from __future__ import annotations

from typing import Any

import mujoco

from energy_margin.errors import EnergyMarginError

__all__ = ["find_mujoco"]

#: Attributes that lead from a wrapper to what it wraps, in the order they are followed.
_INNER = ("unwrapped", "env", "_env")
#: How many wrappers deep the search goes.
_DEPTH = 8


def _pair(model: Any, data: Any) -> tuple[mujoco.MjModel, mujoco.MjData] | None:
    if isinstance(model, mujoco.MjModel) and isinstance(data, mujoco.MjData):
        return model, data
    return None


def _handles_of(thing: Any) -> tuple[mujoco.MjModel, mujoco.MjData] | None:
    """The pair held directly by ``thing`` (itself a pair, or through model/data, sim or physics)."""
    if isinstance(thing, tuple) and len(thing) == 2:
        found = _pair(*thing)
        if found is not None:
            return found
    found = _pair(getattr(thing, "model", None), getattr(thing, "data", None))
    if found is not None:
        return found
    sim = getattr(thing, "sim", None)
    if sim is not None:
        model, data = getattr(sim, "model", None), getattr(sim, "data", None)
        found = _pair(getattr(model, "_model", model), getattr(data, "_data", data))
        if found is not None:
            return found
    physics = getattr(thing, "physics", None)
    if physics is None and hasattr(thing, "model") and hasattr(getattr(thing, "model", None), "ptr"):
        physics = thing
    if physics is not None:
        return _pair(
            getattr(getattr(physics, "model", None), "ptr", None), getattr(getattr(physics, "data", None), "ptr", None)
        )
    return None


def find_mujoco(env: Any, *, what: str | None = None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The ``MjModel`` and ``MjData`` that ``env`` simulates (only read, never copied).

    Args:
        env: an environment or wrapper of any of the stacks in the module docstring, a dm_control
            ``Physics``, or a ``(MjModel, MjData)`` pair.
        what: what the message calls ``env`` (default: its class name).

    Raises:
        EnergyMarginError: no MuJoCo model and data can be found (one line naming what was searched).

    """
    queue: list[tuple[Any, int]] = [(env, 0)]
    seen: set[int] = set()
    while queue:
        thing, depth = queue.pop(0)
        if thing is None or id(thing) in seen:
            continue
        seen.add(id(thing))
        found = _handles_of(thing)
        if found is not None:
            return found
        if depth < _DEPTH:
            for name in _INNER:
                try:
                    inner = getattr(thing, name, None)
                except Exception:  # a wrapper's property may refuse: keep searching
                    inner = None
                queue.append((inner, depth + 1))
    kind = type(getattr(env, "unwrapped", env)).__name__
    raise EnergyMarginError(
        f"{f'{what} ({kind})' if what else kind} has no MuJoCo model: looked for a mujoco.MjModel 'model' and "
        "mujoco.MjData 'data', robosuite's 'sim' and dm_control's 'physics', on it and on what it wraps "
        "(unwrapped, env, _env)"
    )
