"""The figure of a design sweep, as a display object built from its results.

:class:`SweepDisplay` holds what ``results.png`` shows: on the left each design's success rate
(with its 95 % Wilson interval) against its mean early success score, titled with their Spearman
rho; on the right the mean rho of each margin column, and of the success rate itself, against the
success rate of all trajectories when t trajectories per design are used. It is built from the
results of :func:`~energy_margin.design.sweep.design_sweep` by :meth:`SweepDisplay.from_result`
and draws only when asked (:meth:`~energy_margin.runs.display.Display.save`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.design.rank import MARGIN_LABELS, MARGINS
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.display import Display
from energy_margin.runs.results import TypedResult, plain_result
from energy_margin.runs.tables import fmt

__all__ = [
    "SweepDisplay",
]


@dataclass
class SweepDisplay(Display):
    """Success rate against the early margin per design, and rho against t.

    Attributes:
        task: the swept task's name.
        names: the swept parameters, in the order of the grid.
        rows: the analysed designs' table rows (``results["rows"]``).
        correlation: the early success score's entry of ``results["correlations"]``.
        convergence: the rows of ``results["convergence"]``.
        n_trajectories: trajectories per design.
        n_frames: frames per trajectory.
        n_objects: objects per scene.

    """

    task: str
    names: list[str]
    rows: list[dict[str, Any]]
    correlation: dict[str, Any]
    convergence: list[dict[str, Any]]
    n_trajectories: int
    n_frames: int
    n_objects: int | None

    @classmethod
    def from_result(cls, results: TypedResult | dict[str, Any]) -> SweepDisplay:
        """The figure of a sweep's results (or ``results.json``); they must rank at least two designs.

        Raises:
            EnergyMarginError: the results have no correlations (fewer than two analysed designs).

        """
        results = plain_result(results)
        if "correlations" not in results:
            raise EnergyMarginError("a sweep's figure needs at least two analysed designs")
        settings = results["settings"]
        return cls(
            task=settings["task"],
            names=[param["name"] for param in settings["params"]],
            rows=list(results["rows"]),
            correlation=dict(results["correlations"]["early_success_score"]),
            convergence=list(results["convergence"]),
            n_trajectories=settings["n_trajectories"],
            n_frames=settings["n_frames"],
            n_objects=settings["n_objects"],
        )

    def draw(self, plt: Any) -> Any:
        """Draw both panels with pyplot ``plt`` and return the figure."""
        figure, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.2))
        self._draw_designs(left)
        self._draw_convergence(right)
        objects = "" if self.n_objects is None else f", n_o = {self.n_objects}"
        figure.suptitle(
            f"{self.task} design sweep over {', '.join(self.names)}{objects}, "
            f"{self.n_trajectories} x {self.n_frames} frames per design",
            fontsize=11,
        )
        figure.tight_layout()
        return figure

    def _draw_designs(self, axes: Any) -> None:
        rows = self.rows
        x = np.array([row["early_success_score"] for row in rows])
        y = np.array([row["success_rate"] for row in rows])
        error = np.array(
            [
                [r["success_rate"] - r["success_rate_low"] for r in rows],
                [r["success_rate_high"] - r["success_rate"] for r in rows],
            ]
        )
        axes.errorbar(x, y, yerr=error, fmt="o", capsize=3)
        for index, (row, xi, yi) in enumerate(zip(rows, x, y, strict=True)):
            text = ", ".join(json.dumps(row[name]) for name in self.names)
            # Alternate above and below so that neighbouring designs' labels do not overlap.
            offset = (4, 4) if index % 2 == 0 else (4, -10)
            axes.annotate(text, (xi, yi), textcoords="offset points", xytext=offset, fontsize=7)
        rho = fmt(self.correlation["rho"], 2)
        p_value = "" if self.correlation["p_value"] is None else f", p = {self.correlation['p_value']:.3f}"
        axes.set_title(f"Spearman rho = {rho}{p_value} ({len(rows)} designs)", fontsize=10)
        axes.set_xlabel(f"mean {MARGIN_LABELS['early_success_score']}")
        axes.set_ylabel(f"success rate over {self.n_trajectories} trajectories (95 % Wilson)")
        axes.set_ylim(-0.05, 1.05)
        axes.grid(True, alpha=0.3)

    def _draw_convergence(self, axes: Any) -> None:
        convergence = self.convergence
        counts = [row["trajectories"] for row in convergence]
        for name in (*MARGINS, "success_rate"):
            values = [np.nan if row[name] is None else row[name] for row in convergence]
            label = MARGIN_LABELS.get(name, "success rate of t trajectories")
            axes.plot(counts, values, marker="o", linestyle="--" if name == "success_rate" else "-", label=label)
        axes.set_xscale("log")
        axes.set_xticks(counts, [str(count) for count in counts])
        axes.minorticks_off()
        axes.set_xlabel("trajectories t per design")
        axes.set_ylabel(f"mean Spearman rho vs success rate of all {self.n_trajectories}")
        shown = [row[name] for row in convergence for name in (*MARGINS, "success_rate") if row[name] is not None]
        axes.set_ylim(max(-1.05, min(shown, default=0.0) - 0.05), 1.02)
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=8, loc="lower right")
