"""The results of a design search: verified designs, their success rates, the rank correlation, as text.

:func:`verified_entry` turns an evaluation and its verification episodes into a row of
``result.json``'s ``verified`` (Wilson intervals per disturbance level and pooled);
:func:`objective_correlations` is Spearman's rho of the objective with the verified success rate;
:func:`result_csv_fields` and :func:`result_csv_row` lay ``result.csv`` out and
:func:`format_result` prints the table.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin._renamed import renamed_keys
from energy_margin.design.rank import MARGIN_LABELS
from energy_margin.evaluation.statistics import spearman, wilson_interval
from energy_margin.runs.results import TypedResult, plain_result
from energy_margin.runs.tables import Column, field, fmt
from energy_margin.runs.tables import format_table as text_table

__all__ = [
    "DesignSearchResult",
    "best_evaluation",
    "format_result",
    "objective_correlations",
    "result_csv_fields",
    "result_csv_row",
    "verified_entry",
]


@dataclass(frozen=True)
class DesignSearchResult(TypedResult):
    """What :func:`~energy_margin.design.search.design_search` found; ``to_dict()`` is ``result.json``.

    Attributes:
        settings: the search's resolved settings (``design.json``).
        chosen: the verified entry of the search's best design (``None`` when every evaluation failed).
        default: the verified entry of the task's own design.
        grid: the verified entry of the equal-cost grid's best design.
        verified: every verified design (:func:`verified_entry`): values, objective, roll-outs,
            success rate and Wilson interval per disturbance level and pooled.
        search: the optimiser's evaluations, in order.
        grid_evaluations: the equal-cost grid's evaluations.
        default_evaluation: the evaluation of the task's own design.
        evaluations_used: the optimiser's evaluations.
        grid_size: the grid's designs.
        margin_evaluations: distinct designs scored.
        correlation: Spearman's rho of the objective with the verified success rate per level and
            pooled (``None`` without verification).
        picture: ``tool.png`` when the chosen design was drawn (``None`` otherwise).

    """

    settings: dict[str, Any]
    chosen: dict[str, Any] | None
    default: dict[str, Any] | None
    grid: dict[str, Any] | None
    verified: list[dict[str, Any]]
    search: list[dict[str, Any]]
    grid_evaluations: list[dict[str, Any]]
    default_evaluation: dict[str, Any]
    evaluations_used: int
    grid_size: int
    margin_evaluations: int
    correlation: dict[str, Any] | None = None
    picture: str | None = None

    def absent(self) -> set[str]:
        """The correlation without verification, the picture when none was drawn."""
        return {name for name in ("correlation", "picture") if getattr(self, name) is None}


def best_evaluation(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The row of the highest objective (the first of equals); ``None`` when every one failed."""
    best: dict[str, Any] | None = None
    for row in rows:
        if row["objective"] is not None and (best is None or row["objective"] > best["objective"]):
            best = row
    return best


def _rate(successes: list[bool]) -> dict[str, Any]:
    count, trials = int(sum(successes)), len(successes)
    low, high = wilson_interval(count, trials)
    return {"episodes": trials, "successes": count, "success_rate": count / trials, "interval": [low, high]}


def verified_entry(
    row: dict[str, Any], roles: list[str], outcome: dict[str, list[bool]] | None, levels: Sequence[str]
) -> dict[str, Any]:
    """A verified design: its values, objective, roll-outs' success and (once run) its episodes' success rates."""
    entry: dict[str, Any] = {
        "roles": roles,
        "design": row["design"],
        "values": row["values"],
        "phase": row["phase"],
        "index": row["index"],
        "objective": row["objective"],
        "rollout_successes": row.get("rollout_successes"),
        "rollouts": row.get("rollouts"),
        "success_rate": None,
        "interval": None,
        "levels": {},
    }
    if outcome:
        entry["levels"] = {level: _rate(outcome[level]) for level in levels if level in outcome}
        pooled = _rate([success for level in levels for success in outcome.get(level, [])])
        entry.update(success_rate=pooled["success_rate"], interval=pooled["interval"], episodes=pooled["episodes"])
        entry["successes"] = pooled["successes"]
    return entry


def objective_correlations(entries: list[dict[str, Any]], levels: Sequence[str], *, seed: int) -> dict[str, Any]:
    """Spearman's rho of the objective with the verified success rate, per level and pooled (3 designs or more)."""
    rated = [entry for entry in entries if entry["objective"] is not None and entry["success_rate"] is not None]
    x = np.array([entry["objective"] for entry in rated], dtype=float)
    correlations: dict[str, Any] = {}
    for level in [*levels, "pooled"]:
        if level == "pooled":
            y = np.array([entry["success_rate"] for entry in rated], dtype=float)
        else:
            y = np.array([entry["levels"][level]["success_rate"] for entry in rated], dtype=float)
        if len(rated) < 3:
            correlations[level] = {"rho": None, "p_value": None, "exact": True, "n": len(rated)}
            continue
        found = spearman(x, y, seed=seed)
        correlations[level] = {"rho": found.rho, "p_value": found.p_value, "exact": found.exact, "n": found.n}
    return correlations


def result_csv_fields(result: dict[str, Any], names: list[str]) -> list[str]:
    """The columns of ``result.csv``: roles, design, the parameters ``names``, per-level and pooled rates."""
    levels = list(result["settings"]["verify"]["disturbances"])
    per_level = [f"{level}_{key}" for level in levels for key in ("successes", "success_rate", "low", "high")]
    return [
        "roles",
        "design",
        *names,
        "objective",
        "rollout_successes",
        "rollouts",
        *per_level,
        "success_rate",
        "low",
        "high",
    ]


def result_csv_row(entry: dict[str, Any]) -> dict[str, Any]:
    """A verified design ``entry`` as one row of ``result.csv``."""
    row: dict[str, Any] = {**entry, **entry["values"], "roles": " ".join(entry["roles"])}
    if entry["interval"] is not None:
        row["low"], row["high"] = entry["interval"]
    for level, rate in entry["levels"].items():
        row[f"{level}_successes"] = rate["successes"]
        row[f"{level}_success_rate"] = rate["success_rate"]
        row[f"{level}_low"], row[f"{level}_high"] = rate["interval"]
    return row


def _rate_text(rate: dict[str, Any] | None) -> str:
    if rate is None:
        return "n/a"
    low, high = rate["interval"]
    return f"{rate['successes']}/{rate['episodes']} {rate['success_rate']:.2f} [{low:.2f}, {high:.2f}]"


def _role(entry: dict[str, Any]) -> str:
    return "+".join(entry["roles"]) or f"{entry['phase']} {entry['index'] + 1}"


def _rollouts(entry: dict[str, Any]) -> str:
    return "" if entry["rollouts"] is None else f"{entry['rollout_successes']}/{entry['rollouts']}"


def _value_cell(name: str) -> Callable[[dict[str, Any]], str]:
    return lambda entry: json.dumps(entry["values"][name])


def _level_cell(level: str) -> Callable[[dict[str, Any]], str]:
    return lambda entry: _rate_text(entry["levels"].get(level))


def format_result(result: DesignSearchResult | dict[str, Any]) -> str:
    """The verified designs as a table, then what was searched and the rank correlation, as text."""
    result = plain_result(result)
    settings = result["settings"]
    names = [p["name"] for p in settings["space"]]
    levels = list(settings["verify"]["disturbances"])
    score = settings["objective"]["score"]
    columns = [
        Column("design", _role, 8, "<"),
        *(Column(name, _value_cell(name), 8) for name in names),
        field("objective", digits=4, width=9),
        Column("roll-outs", _rollouts, 9),
        *(Column(f"{level} [95 % Wilson]", _level_cell(level), 22) for level in levels),
        Column("all levels", lambda e: _rate_text(_pooled(e)), 22),
    ]
    lines = [text_table(result["verified"], columns)]
    failed = sum(1 for row in result["search"] if row["objective"] is None)
    lines.append("")
    lines.append(
        f"objective: mean {MARGIN_LABELS.get(score, score)} of {settings['n_trajectories']} roll-outs x "
        f"{settings['n_frames']} frames ({_objective_text(settings['objective'])}); {settings['optimizer']} used "
        f"{result['evaluations_used']} evaluations"
        + (f" ({failed} failed)" if failed else "")
        + f"; the equal-cost grid {result['grid_size']} ({' x '.join(str(c) for c in settings['grid']['counts'])})"
    )
    correlation = result.get("correlation")
    if correlation:
        parts = []
        for level in [*levels, "pooled"]:
            entry = correlation[level]
            p_value = "" if entry["p_value"] is None else f", p {_p_text(entry['p_value'])}"
            parts.append(f"{level} {fmt(entry['rho'], 2)}{p_value}")
        n = correlation["pooled"]["n"]
        lines.append(f"Spearman rho of the objective with the verified success rate ({n} designs): {'; '.join(parts)}")
    return "\n".join(lines)


def _pooled(entry: dict[str, Any]) -> dict[str, Any] | None:
    if entry["success_rate"] is None:
        return None
    return {
        "successes": entry["successes"],
        "episodes": entry["episodes"],
        "success_rate": entry["success_rate"],
        "interval": entry["interval"],
    }


def _p_text(p_value: float) -> str:
    return "< 0.001" if p_value < 0.001 else f"= {p_value:.3f}"


def _objective_text(objective: dict[str, Any]) -> str:
    if objective["kind"] == "margin":
        return f"tree of {renamed_keys(objective['analyzer'])['expansions']} expansions a frame"
    return "learned margin"
