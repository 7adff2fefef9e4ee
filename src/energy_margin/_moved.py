"""Import paths of release 0.1.0 that moved when the package was grouped into pipeline stages.

``energy_margin.dataset``, ``energy_margin.analysis.load_scores`` and the other flat paths of 0.1.0
keep working for one release: importing one emits a :class:`DeprecationWarning` that names the new
home, then resolves every name from the stage modules. CHANGELOG.md lists the moves. This module
imports no stage at import time: the new homes load only when an old path is used.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from collections.abc import Callable
from typing import Any

__all__ = [
    "MOVED_MODULES",
    "RENAMED",
    "install",
    "stage_getattr",
]

#: Old module of 0.1.0 -> the modules that now hold its names, searched in order.
MOVED_MODULES: dict[str, tuple[str, ...]] = {
    "energy_margin.scene": ("energy_margin.world.scene",),
    "energy_margin.state": ("energy_margin.world.state",),
    "energy_margin.ellipsoid": ("energy_margin.world.ellipsoid",),
    "energy_margin.energy": ("energy_margin.planning.costs",),
    "energy_margin.scores": ("energy_margin.analysis.scores",),
    "energy_margin.executors": ("energy_margin.analysis.executors",),
    "energy_margin.analysis": (
        "energy_margin.analysis.frame",
        "energy_margin.analysis.run",
        "energy_margin.data.scores_file",
    ),
    "energy_margin.dataset": (
        "energy_margin.data.dataset",
        "energy_margin.data.dataset_files",
        "energy_margin.data.generate",
        "energy_margin.data.scores_file",
    ),
    "energy_margin.io": ("energy_margin.runs.files",),
    "energy_margin.data.io": ("energy_margin.runs.files",),
    "energy_margin.validation": ("energy_margin.data.validation",),
    "energy_margin.reference": ("energy_margin.data.reference",),
    "energy_margin.perturb": ("energy_margin.robustness.perturb",),
    "energy_margin.robustness": ("energy_margin.robustness.compare",),
    "energy_margin.baselines": ("energy_margin.evaluation.baselines",),
    "energy_margin.budget": ("energy_margin.experiments.budget",),
    # 0.2: design and the research protocols left evaluation.
    "energy_margin.evaluation.designs": ("energy_margin.design.grid", "energy_margin.design.params"),
    "energy_margin.evaluation.design_space": ("energy_margin.design.space", "energy_margin.design.params"),
    "energy_margin.evaluation.design_optimizers": ("energy_margin.design.optimizers",),
    "energy_margin.evaluation.design_search": ("energy_margin.design.search",),
    "energy_margin.evaluation.design_display": ("energy_margin.design.search_display",),
    "energy_margin.evaluation.sweep": ("energy_margin.design.sweep",),
    "energy_margin.evaluation.sweep_display": ("energy_margin.design.sweep_display",),
    "energy_margin.evaluation.sweep_results": ("energy_margin.design.sweep_results",),
    "energy_margin.evaluation.rank": ("energy_margin.design.rank",),
    "energy_margin.control.verification": ("energy_margin.design.verification",),
    "energy_margin.evaluation.budget": ("energy_margin.experiments.budget", "energy_margin.data.dataset_files"),
    "energy_margin.evaluation.budget_display": ("energy_margin.experiments.budget_display",),
    "energy_margin.evaluation.study": ("energy_margin.experiments.study",),
    "energy_margin.evaluation.study_display": ("energy_margin.experiments.study_display",),
    "energy_margin.evaluation.study_result": ("energy_margin.experiments.study_result",),
    "energy_margin.evaluation.study_state": ("energy_margin.experiments.study_state",),
    "energy_margin.plots": ("energy_margin.report.plots",),
    "energy_margin.report": ("energy_margin.report.html",),
    "energy_margin.reproduce": (
        "energy_margin.report.reproduce",
        "energy_margin.report.config",
        "energy_margin.report.paper",
    ),
}

#: Names that became public when they moved.
RENAMED = {
    "_check_target": "check_target",
    "_write_directory": "write_directory",
    "_format_row": "format_row",
    "_parse_row": "parse_row",
    "_header": "header",
    "parse_search_param": "parse_param",
}


def _warn(old: str, new: str) -> None:
    warnings.warn(
        f"{old} moved to {new} (see CHANGELOG.md); the old path goes in 0.3", DeprecationWarning, stacklevel=3
    )


def _lookup(old_module: str, name: str) -> Any:
    """Find ``name`` of ``old_module`` in its new homes; raise :class:`AttributeError` when absent."""
    target = RENAMED.get(name, name)
    for new in MOVED_MODULES[old_module]:
        module = importlib.import_module(new)
        if hasattr(module, target):
            _warn(f"{old_module}.{name}", f"{new}.{target}")
            return getattr(module, target)
    raise AttributeError(f"module {old_module!r} has no attribute {name!r}")


def stage_getattr(package: str) -> Callable[[str], Any]:
    """A module ``__getattr__`` for a stage package whose name was a flat module in 0.1.0.

    Args:
        package: the package, e.g. ``"energy_margin.analysis"``.

    Returns:
        The function to bind as the package's ``__getattr__``.
    """

    def module_getattr(name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return _lookup(package, name)

    return module_getattr


class _MovedModule(types.ModuleType):
    """Stands in for a flat module of 0.1.0; every attribute comes from the new homes."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return _lookup(self.__name__, name)


class _Loader(importlib.abc.Loader):
    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        return _MovedModule(spec.name)

    def exec_module(self, module: types.ModuleType) -> None:
        homes = ", ".join(MOVED_MODULES[module.__name__])
        _warn(module.__name__, homes)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        del path, target
        # Consulted after the regular finders: the stage packages that kept an old name
        # (analysis, robustness, report) are found as packages before this finder is asked.
        if fullname not in MOVED_MODULES:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Loader())


def install() -> None:
    """Serve the flat module paths of 0.1.0 (idempotent)."""
    if not any(isinstance(finder, _Finder) for finder in sys.meta_path):
        sys.meta_path.append(_Finder())
