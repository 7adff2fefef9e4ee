"""Design a task's tool with the margin: sweep a grid of designs or search a design space.

:mod:`~energy_margin.design.params` reads the one ``NAME=LOW:HIGH | NAME=A,B,C`` grammar of a
design parameter; :mod:`~energy_margin.design.grid` makes the grid of designs a sweep runs and
:mod:`~energy_margin.design.space` the space a search explores; :mod:`~energy_margin.design.rank`
measures how a design's margins rank its outcomes; :mod:`~energy_margin.design.sweep` runs a sweep
(tables in :mod:`~energy_margin.design.sweep_results`, figure in
:mod:`~energy_margin.design.sweep_display`); :mod:`~energy_margin.design.optimizers` (CMA-ES, TPE,
an even grid) propose designs to :mod:`~energy_margin.design.search`, whose best design
:mod:`~energy_margin.design.verification` checks in closed-loop episodes; its figure is
:mod:`~energy_margin.design.search_display`.

Imported names load their modules on first use, so ``import energy_margin.design`` is cheap.
"""

from __future__ import annotations

from energy_margin._lazy import lazy_getattr

#: Public name -> the module that defines it.
_HOMES = {
    "Design": "energy_margin.design.grid",
    "design_grid": "energy_margin.design.grid",
    "DesignParam": "energy_margin.design.params",
    "parse_param": "energy_margin.design.params",
    "resolve_space": "energy_margin.design.space",
    "design_sweep": "energy_margin.design.sweep",
    "SweepDisplay": "energy_margin.design.sweep_display",
    "OPTIMIZERS": "energy_margin.design.optimizers",
    "design_search": "energy_margin.design.search",
    "TreeScorer": "energy_margin.design.search",
    "DesignSearchDisplay": "energy_margin.design.search_display",
    "EpisodeVerifier": "energy_margin.design.verification",
}

__all__ = sorted(_HOMES)

__getattr__ = lazy_getattr("energy_margin.design", _HOMES)
