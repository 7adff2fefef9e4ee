"""Success continuation by default: what ``analyze`` draws when no continuation is given.

A tree reaches about a second past its frame. Where the nominal motion reaches the success region
later, no tree state of an early frame lies in it and the tree's own success score is exactly 0;
continuing the motion from the tree's nodes (:mod:`energy_margin.analysis.continuation`) ranks
early success there, and measured on every example and both built-in tasks it ranked early success
better than or level with the tree's own score on the sets used to choose it (docs/howto/scenes.md,
"Success beyond a tree's reach"). ``analyze`` with ``continuation=None`` (its default,
``--continuation auto``) therefore draws :data:`AUTO_SAMPLES` continuations per frame on an engine
that :attr:`~energy_margin.sim.Engine.continues` and keeps the tree's own score on one that cannot.
The decision is recorded with the analysis (``continuation_choice`` in ``analysis.json``), so a
resumed run keeps it, including a decision recorded by an earlier release's pilot rule.
"""

from __future__ import annotations

from typing import Any

from energy_margin.sim import get_engine

__all__ = ["AUTO_SAMPLES", "default_continuation", "recorded_choice"]

#: Continuations drawn per frame by default (chosen on generation seed 11,
#: docs/howto/scenes.md, "Success beyond a tree's reach").
AUTO_SAMPLES = 16


def default_continuation(engine: str) -> int:
    """Continuations drawn per frame by default on the engine named ``engine`` (0: the tree's own score)."""
    return AUTO_SAMPLES if get_engine(engine).continues else 0


def recorded_choice(description: dict[str, Any]) -> int | None:
    """The continuation an analysis recorded as decided by default (``None``: none recorded)."""
    choice = description.get("continuation_choice")
    if isinstance(choice, dict) and isinstance(choice.get("continuation"), int):
        return int(choice["continuation"])
    return None
