"""The research protocols: the budget sweep and the study across tasks, methods and lambdas.

:mod:`~energy_margin.experiments.budget` scores one dataset at several expansion budgets and
methods and tabulates AP against time per frame (figure:
:mod:`~energy_margin.experiments.budget_display`); :mod:`~energy_margin.experiments.study` runs
the protocol of the study on freshly generated sets (its state in
:mod:`~energy_margin.experiments.study_state`, its tables in
:mod:`~energy_margin.experiments.study_result`, its figures in
:mod:`~energy_margin.experiments.study_display`).

Imported names load their modules on first use, so ``import energy_margin.experiments`` is cheap.
"""

from __future__ import annotations

from energy_margin._lazy import lazy_getattr

#: Public name -> the module that defines it.
_HOMES = {
    "budget_sweep": "energy_margin.experiments.budget",
    "BudgetSweepResult": "energy_margin.experiments.budget",
    "BudgetDisplay": "energy_margin.experiments.budget_display",
    "run_study": "energy_margin.experiments.study",
    "StudyResult": "energy_margin.experiments.study_result",
    "LambdaDisplay": "energy_margin.experiments.study_display",
}

__all__ = sorted(_HOMES)

__getattr__ = lazy_getattr("energy_margin.experiments", _HOMES)
