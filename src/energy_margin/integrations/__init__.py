"""Energy margins inside the simulators users already have: Gymnasium, robosuite, Meta-World, dm_control.

* :func:`find_mujoco` (:mod:`~energy_margin.integrations.handles`): the ``MjModel`` / ``MjData``
  behind an environment of any of those stacks.
* :class:`LiveModelScorer` (:mod:`~energy_margin.integrations.live_model`): scores the state of a
  user's ``MjModel`` / ``MjData``, the mechanism under every wrapper, and the episode recorder.
* :mod:`energy_margin.integrations.gymnasium`: ``MarginWrapper`` (``pip install 'energy-margin[gymnasium]'``).
* :mod:`energy_margin.integrations.dm_control`: ``MarginEnvironment`` and ``PhysicsScorer``
  (``pip install 'energy-margin[dm]'``).
* :mod:`energy_margin.integrations.gym_scene`: a starter scene file from a Gymnasium environment.

Nothing here is imported by ``import energy_margin``; the names below load on first use, and the
Gymnasium and dm_control modules import their simulator library.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["LiveModelScorer", "LiveOptions", "MarginEnvironment", "MarginWrapper", "PhysicsScorer", "find_mujoco"]

_LAZY = {
    "LiveModelScorer": "energy_margin.integrations.live_model",
    "LiveOptions": "energy_margin.integrations.live_model",
    "MarginEnvironment": "energy_margin.integrations.dm_control",
    "MarginWrapper": "energy_margin.integrations.gymnasium",
    "PhysicsScorer": "energy_margin.integrations.dm_control",
    "find_mujoco": "energy_margin.integrations.handles",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'energy_margin.integrations' has no attribute {name!r}")
