"""The optimisers of a design search, one ask/tell interface over well-kept libraries.

* ``cma``: CMA-ES of the ``cma`` package on the space scaled to the unit box (bounded, started at
  its centre with step 0.3), numeric axes only. A whole-valued axis is rounded. CMA-ES needs two
  dimensions at least: a one-axis space gets an inert second coordinate.
* ``tpe``: Optuna's ``TPESampler`` (seeded; its default 10 random start-up trials, then the
  tree-structured Parzen estimator), numeric and categorical axes.
* ``grid``: the even grid of :func:`~energy_margin.design.space.even_grid`, no library.

Every optimiser maximises: :meth:`Optimizer.ask` gives the next point (a value per axis) and
:meth:`Optimizer.tell` its objective. The libraries are imported when an optimiser is made, so
``energy_margin`` imports without them; :func:`require_optimizer` refuses, in one line naming the
``design`` extra, an optimiser whose library is not installed. Each is deterministic for a seed:
the same tells give the same asks, which is how a search resumes (its journal is told again).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any, Protocol

import numpy as np

from energy_margin.design.space import even_grid
from energy_margin.errors import EnergyMarginError, check_choice
from energy_margin.tasks import DesignParameter

__all__ = [
    "CMA_SIGMA",
    "OPTIMIZERS",
    "PACKAGES",
    "CmaOptimizer",
    "GridOptimizer",
    "Optimizer",
    "TpeOptimizer",
    "make_optimizer",
    "require_optimizer",
]

#: The optimisers of ``design --optimizer``.
OPTIMIZERS = ("cma", "tpe", "grid")
#: The package each optimiser imports (all in the ``design`` extra).
PACKAGES = {"cma": "cma", "tpe": "optuna"}
#: CMA-ES's initial step on the unit box.
CMA_SIGMA = 0.3


class Optimizer(Protocol):
    """Asks for points and is told their objective (maximised)."""

    #: The most points it proposes (``None``: as many as asked for).
    limit: int | None

    def ask(self) -> list[Any]:
        """The next point: one value per axis."""

    def tell(self, value: float) -> None:
        """The objective of the last point asked for."""


def require_optimizer(name: str, space: Sequence[DesignParameter]) -> None:
    """Refuse an unknown optimiser, ``cma`` over a categorical axis, or an optimiser whose library is missing.

    Raises:
        EnergyMarginError: one line each (the missing library names the ``design`` extra).

    """
    check_choice("optimizer", name, OPTIMIZERS)
    if name == "cma":
        categorical = [parameter.name for parameter in space if parameter.choices is not None]
        if categorical:
            raise EnergyMarginError(
                f"`optimizer=cma` searches numeric ranges only and {categorical[0]} is categorical; "
                "use `optimizer=tpe` or grid"
            )
    package = PACKAGES.get(name)
    if package is not None:
        try:
            importlib.import_module(package)
        except ImportError:
            raise EnergyMarginError(
                f"`optimizer={name}` needs the {package} package: pip install 'energy-margin[design]'"
            ) from None


def make_optimizer(name: str, space: Sequence[DesignParameter], *, budget: int, seed: int) -> Optimizer:
    """The optimiser ``name`` over ``space`` for ``budget`` evaluations, seeded (see :func:`require_optimizer`)."""
    require_optimizer(name, space)
    if name == "cma":
        return CmaOptimizer(space, seed=seed)
    if name == "tpe":
        return TpeOptimizer(space, seed=seed)
    return GridOptimizer(space, budget=budget)


def _bounds(parameter: DesignParameter) -> tuple[float, float]:
    assert parameter.low is not None and parameter.high is not None
    return parameter.low, parameter.high


class CmaOptimizer:
    """CMA-ES (``cma``) on the unit box; its random draws kept apart from numpy's global generator."""

    limit: int | None = None

    def __init__(self, space: Sequence[DesignParameter], *, seed: int) -> None:
        import cma

        self.space = list(space)
        dimension = max(2, len(self.space))
        options = {
            "bounds": [[0.0] * dimension, [1.0] * dimension],
            # cma takes 0 for "seed from the clock": shift the seed by one.
            "seed": seed % (2**32 - 1) + 1,
            "verbose": -9,
            "verb_log": 0,
            "verb_disp": 0,
        }
        self._state = np.random.RandomState(0).get_state()
        with self._own_generator():
            self._strategy = cma.CMAEvolutionStrategy([0.5] * dimension, CMA_SIGMA, options)
        self._population: list[np.ndarray] = []
        self._values: list[float] = []

    @contextmanager
    def _own_generator(self) -> Iterator[None]:
        # cma draws from numpy's global generator: swap in its own state so that nothing else
        # (a replayed search draws nothing between asks, a running one may) changes its draws.
        outer = np.random.get_state()
        np.random.set_state(self._state)
        try:
            yield
        finally:
            self._state = np.random.get_state()
            np.random.set_state(outer)

    def ask(self) -> list[Any]:
        """The next member of the current generation (a new generation once the last is told)."""
        if len(self._values) == len(self._population):
            with self._own_generator():
                self._population = [np.asarray(x, dtype=float) for x in self._strategy.ask()]
            self._values = []
        x = np.clip(self._population[len(self._values)], 0.0, 1.0)
        point: list[Any] = []
        for parameter, unit in zip(self.space, x, strict=False):
            low, high = _bounds(parameter)
            point.append(low + float(unit) * (high - low))
        return point

    def tell(self, value: float) -> None:
        """Record the objective; the generation is told to CMA-ES (which minimises -objective) once complete."""
        self._values.append(-float(value))
        if len(self._values) == len(self._population):
            with self._own_generator():
                self._strategy.tell(self._population, self._values)


@contextmanager
def _quiet_optuna(optuna: Any) -> Iterator[None]:
    verbosity = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        yield
    finally:
        optuna.logging.set_verbosity(verbosity)


class TpeOptimizer:
    """Optuna's seeded ``TPESampler`` through its ask/tell interface (a study in memory)."""

    limit: int | None = None

    def __init__(self, space: Sequence[DesignParameter], *, seed: int) -> None:
        import optuna
        from optuna.distributions import BaseDistribution, CategoricalDistribution, FloatDistribution, IntDistribution

        self._optuna = optuna
        self.space = list(space)
        self._distributions: dict[str, BaseDistribution] = {}
        for parameter in self.space:
            if parameter.choices is not None:
                # Indices: a value may be any JSON (a list), which optuna's choices may not.
                self._distributions[parameter.name] = CategoricalDistribution(tuple(range(len(parameter.choices))))
            elif parameter.integer:
                low, high = _bounds(parameter)
                self._distributions[parameter.name] = IntDistribution(int(low), int(high))
            else:
                self._distributions[parameter.name] = FloatDistribution(*_bounds(parameter))
        with _quiet_optuna(optuna):
            self._study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=seed))
        self._trial: Any = None

    def ask(self) -> list[Any]:
        """The next trial's values."""
        with _quiet_optuna(self._optuna):
            self._trial = self._study.ask(self._distributions)
        point: list[Any] = []
        for parameter in self.space:
            value = self._trial.params[parameter.name]
            point.append(parameter.choices[value] if parameter.choices is not None else value)
        return point

    def tell(self, value: float) -> None:
        """Complete the last trial with ``value``."""
        with _quiet_optuna(self._optuna):
            self._study.tell(self._trial, float(value))


class GridOptimizer:
    """The even grid of at most ``budget`` points, in product order."""

    def __init__(self, space: Sequence[DesignParameter], *, budget: int) -> None:
        self._points = even_grid(space, budget)
        self.limit: int | None = len(self._points)
        self._next = 0

    def ask(self) -> list[Any]:
        """The next grid point."""
        point = self._points[self._next]
        self._next += 1
        return list(point)

    def tell(self, value: float) -> None:
        """Nothing to learn."""
        del value
