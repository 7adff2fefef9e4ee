"""The figure of a design search, as a display object built from its result.

:class:`DesignSearchDisplay` holds what ``search.png`` shows: on the left the objective of each
evaluation against its number, the best so far as a step line, the equal-cost grid's designs
(against their own number) and its best as a dashed line, the default design's objective as a
dotted one; on the right, once verified, each verified design's success rate (95 % Wilson
interval, every disturbance level) against its objective, titled with Spearman's rho. It is built
from the result of :func:`~energy_margin.design.search.design_search` by
:meth:`DesignSearchDisplay.from_result` and draws only when asked.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.design.rank import MARGIN_LABELS
from energy_margin.runs.display import Display
from energy_margin.runs.results import TypedResult, plain_result
from energy_margin.runs.tables import fmt

__all__ = [
    "DesignSearchDisplay",
]


@dataclass
class DesignSearchDisplay(Display):
    """Objective against evaluation number, and verified success rate against objective.

    Attributes:
        task: the task's name.
        optimizer: the optimiser's name.
        score: the score column of the objective.
        search: the objective of each of the optimiser's evaluations (``None``: failed).
        grid: the objective of each of the equal-cost grid's designs.
        default: the default design's objective.
        verified: the verified designs (``result["verified"]``).
        levels: the verification's disturbance levels.
        correlation: ``result["correlation"]`` (empty before the verification).

    """

    task: str
    optimizer: str
    score: str
    search: list[float | None]
    grid: list[float | None]
    default: float | None
    verified: list[dict[str, Any]]
    levels: list[str]
    correlation: dict[str, Any]

    @classmethod
    def from_result(cls, result: TypedResult | dict[str, Any]) -> DesignSearchDisplay:
        """The figure of a design search's result (or ``result.json``)."""
        result = plain_result(result)
        settings = result["settings"]
        return cls(
            task=settings["task"],
            optimizer=settings["optimizer"],
            score=settings["objective"]["score"],
            search=[row["objective"] for row in result["search"]],
            grid=[row["objective"] for row in result["grid_evaluations"]],
            default=result["default_evaluation"]["objective"],
            verified=list(result["verified"]),
            levels=list(settings["verify"]["disturbances"]),
            correlation=dict(result.get("correlation") or {}),
        )

    def draw(self, plt: Any) -> Any:
        """Draw the panels with pyplot ``plt`` and return the figure."""
        verified = any(entry["success_rate"] is not None for entry in self.verified)
        figure, axes = plt.subplots(1, 2 if verified else 1, figsize=(11.0 if verified else 6.0, 4.2))
        panels = list(axes) if verified else [axes]
        self._draw_search(panels[0])
        if verified:
            self._draw_verification(panels[1])
        figure.suptitle(f"{self.task} design search ({self.optimizer}, {len(self.search)} evaluations)", fontsize=11)
        figure.tight_layout()
        return figure

    def _draw_search(self, axes: Any) -> None:
        numbers = np.arange(1, len(self.search) + 1)
        values = np.array([np.nan if v is None else v for v in self.search], dtype=float)
        failed = np.isnan(values)
        axes.plot(numbers[~failed], values[~failed], "o", color="C0", label=f"{self.optimizer} evaluations")
        if failed.any():
            axes.plot(numbers[failed], np.zeros(int(failed.sum())), "x", color="C3", label="failed (told 0)")
        best = np.fmax.accumulate(np.where(failed, -np.inf, values))
        shown = np.isfinite(best)
        axes.step(numbers[shown], best[shown], where="post", color="C0", label="best so far")
        grid = np.array([np.nan if v is None else v for v in self.grid], dtype=float)
        if grid.size:
            axes.plot(np.arange(1, grid.size + 1), grid, "s", color="C2", alpha=0.6, mfc="none", label="grid designs")
            if np.isfinite(grid).any():
                axes.axhline(float(np.nanmax(grid)), color="C2", linestyle="--", label="grid best")
        if self.default is not None:
            axes.axhline(self.default, color="0.4", linestyle=":", label="default design")
        axes.set_xlabel("evaluation")
        axes.ticklabel_format(axis="y", useOffset=False)
        axes.set_ylabel(f"objective: mean {MARGIN_LABELS.get(self.score, self.score)}")
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=8, loc="lower right")

    def _draw_verification(self, axes: Any) -> None:
        rated = [e for e in self.verified if e["success_rate"] is not None and e["objective"] is not None]
        markers = ("o", "s", "^", "v", "D")
        for number, level in enumerate(self.levels):
            x = np.array([e["objective"] for e in rated], dtype=float)
            rates = [e["levels"][level] for e in rated]
            y = np.array([r["success_rate"] for r in rates], dtype=float)
            error = np.array(
                [
                    [r["success_rate"] - r["interval"][0] for r in rates],
                    [r["interval"][1] - r["success_rate"] for r in rates],
                ]
            )
            axes.errorbar(x, y, yerr=error, fmt=markers[number % len(markers)], capsize=3, label=level)
        named = [entry for entry in rated if entry["roles"]]
        for number, entry in enumerate(named):
            # Staggered: the chosen, default and grid designs often lie close together.
            axes.annotate(
                "+".join(entry["roles"]),
                (entry["objective"], entry["success_rate"]),
                textcoords="offset points",
                xytext=(-40, 12 + 10 * number),
                fontsize=7,
                arrowprops={"arrowstyle": "-", "color": "0.5", "lw": 0.5},
            )
        pooled = self.correlation.get("pooled", {})
        title = f"Spearman rho = {fmt(pooled.get('rho'), 2)} ({pooled.get('n', len(rated))} designs, all levels)"
        axes.set_title(title, fontsize=10)
        axes.set_xlabel("objective")
        axes.ticklabel_format(axis="x", useOffset=False)
        axes.locator_params(axis="x", nbins=5)
        axes.set_ylabel("verified success rate (95 % Wilson)")
        axes.set_ylim(-0.05, 1.05)
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=8, loc="lower right")
