"""The results of a design sweep: gathered, written as CSV, JSON and a figure, printed as text.

:func:`design_row` is the table row of an analysed design, :func:`failed_row` that of a design
that was not analysed; :func:`summarize` gathers the analysed designs' rows, the rank statistics of
:mod:`~energy_margin.design.rank` and the per-trajectory values into the contents of
``results.json``; :func:`write_results` writes the table (``results.csv``), that object
(``results.json``) and the figure (``results.png``, a
:class:`~energy_margin.design.sweep_display.SweepDisplay`); :func:`format_table` is the text
the command prints.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path
from typing import Any

from energy_margin.data.dataset import load_dataset
from energy_margin.design.grid import Design
from energy_margin.design.rank import MARGIN_LABELS, MARGINS, DesignOutcome, rank_convergence, rank_correlations
from energy_margin.design.sweep_display import SweepDisplay
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.statistics import wilson_interval
from energy_margin.runs.results import TypedResult, plain_result
from energy_margin.runs.tables import Column, field, fmt, write_csv, write_json
from energy_margin.runs.tables import format_table as text_table

__all__ = [
    "CONVERGENCE_COLUMNS",
    "DESIGN_COLUMNS",
    "FIGURE_FILE",
    "RESULTS_FILE",
    "RESULTS_JSON",
    "SweepResult",
    "design_row",
    "failed_row",
    "format_table",
    "summarize",
    "table_fields",
    "write_results",
]

RESULTS_FILE = "results.csv"
RESULTS_JSON = "results.json"
FIGURE_FILE = "results.png"


def design_row(design: Design, outcome: DesignOutcome) -> dict[str, Any]:
    """The table row of one design: its values, success rate with Wilson interval and mean scores."""
    trials = int(outcome.success.size)
    successes = int(outcome.success.sum())
    low, high = wilson_interval(successes, trials)
    row: dict[str, Any] = {"design": design.slug, **design.values}
    row.update(
        trajectories=trials,
        successes=successes,
        success_rate=successes / trials,
        success_rate_low=low,
        success_rate_high=high,
    )
    for name in MARGINS:
        row[name] = float(outcome.column(name).mean())
    row["runtime_per_frame_s"] = outcome.runtime_per_frame_s
    return row


def failed_row(design: Design, directory: Path, error: str) -> dict[str, Any]:
    """The row of a design that was not analysed: its values, the labels' success rate if generated, the error."""
    row: dict[str, Any] = {"design": design.slug, **design.values}
    try:
        success = load_dataset(directory).success_labels()
    except EnergyMarginError:
        success = None
    if success is not None:
        low, high = wilson_interval(int(success.sum()), int(success.size))
        row.update(
            trajectories=int(success.size),
            successes=int(success.sum()),
            success_rate=float(success.mean()),
            success_rate_low=low,
            success_rate_high=high,
        )
    row["error"] = error
    return row


@dataclass(frozen=True)
class SweepResult(TypedResult):
    """What :func:`~energy_margin.design.sweep.design_sweep` measured; ``to_dict()`` is ``results.json``.

    Attributes:
        settings: the sweep's resolved settings (``sweep.json``).
        rows: one row per analysed design (:func:`design_row`).
        correlations: the rank correlations of each margin with the designs' success
            (``None`` with fewer than two analysed designs).
        convergence: the rank correlation against the trajectories per design (``None`` likewise).
        trajectories: per design, every trajectory's success and margins.
        failed: the designs that could not be generated or analysed (:func:`failed_row`).

    """

    settings: dict[str, Any]
    rows: list[dict[str, Any]]
    correlations: dict[str, Any] | None = None
    convergence: dict[str, Any] | None = None
    trajectories: dict[str, Any] = dataclass_field(default_factory=dict)
    failed: list[dict[str, Any]] = dataclass_field(default_factory=list)

    def absent(self) -> set[str]:
        """The rank statistics before two designs are analysed."""
        return {name for name in ("correlations", "convergence") if getattr(self, name) is None}


def summarize(
    settings: dict[str, Any],
    rows: list[dict[str, Any]],
    outcomes: Sequence[DesignOutcome],
    counts: Sequence[int],
    *,
    seed: int,
    bootstrap: int,
    subsets: int,
) -> dict[str, Any]:
    """The results of the designs analysed so far (correlations once two designs are in)."""
    results: dict[str, Any] = {"settings": settings, "rows": rows}
    if len(outcomes) >= 2:
        results["correlations"] = rank_correlations(outcomes, seed=seed, bootstrap=bootstrap)
        results["convergence"] = rank_convergence(outcomes, counts, subsets=subsets, seed=seed)
    results["trajectories"] = {
        row["design"]: {
            "success": outcome.success.astype(int).tolist(),
            **{name: outcome.column(name).tolist() for name in MARGINS},
        }
        for row, outcome in zip(rows, outcomes, strict=True)
    }
    return results


def table_fields(results: dict[str, Any]) -> list[str]:
    """The CSV columns: design, the swept parameters, then the measured values."""
    names = [param["name"] for param in results["settings"]["params"]]
    measured = ["trajectories", "successes", "success_rate", "success_rate_low", "success_rate_high"]
    return ["design", *names, *measured, *MARGINS, "runtime_per_frame_s", "error"]


def write_results(out: Path, results: dict[str, Any]) -> list[Path]:
    """Write ``results.csv``, ``results.json`` and (with matplotlib, two designs or more) ``results.png`` in ``out``."""
    out = Path(out)
    rows = [*results["rows"], *results.get("failed", [])]
    written = [write_csv(out / RESULTS_FILE, rows, table_fields(results)), write_json(out / RESULTS_JSON, results)]
    if "correlations" in results:
        figure = SweepDisplay.from_result(results).save(out / FIGURE_FILE)
        if figure is not None:
            written.append(figure)
    return written


def _value(name: str, width: int) -> Column:
    """The column of a swept parameter's value, as JSON."""
    return Column(name, lambda row: json.dumps(row[name]), width)


#: The measured columns of the design table.
DESIGN_COLUMNS = (
    Column("success", lambda row: f"{row['successes']:>4d}/{row['trajectories']:<3d}", 8),
    Column(
        "rate [95 % Wilson]",
        lambda row: f"{row['success_rate']:.2f} [{row['success_rate_low']:.2f}, {row['success_rate_high']:.2f}]",
        20,
    ),
    field("early_success_score", "early succ", digits=4, width=10),
    field("success_score", "succ score", digits=4, width=10),
    field("capture_score", "capture", digits=4, width=8),
    field("runtime_per_frame_s", "s/frame", digits=3, width=8),
)

#: The columns of the table "from t trajectories per design" (rho to two decimals).
CONVERGENCE_COLUMNS = (
    field("trajectories", "t", width=4),
    field("early_success_score", "early succ", digits=2, width=10),
    field("success_score", "succ score", digits=2, width=10),
    field("capture_score", "capture", digits=2, width=8),
    field("success_rate", "succ rate", digits=2, width=10),
)


def format_table(results: SweepResult | dict[str, Any]) -> str:
    """The design table, the rank correlations and the convergence table as text."""
    results = plain_result(results)
    names = [param["name"] for param in results["settings"]["params"]]
    failed = results.get("failed", [])
    everyone = [*results["rows"], *failed]
    widths = [max([len(name), 8, *(len(json.dumps(row[name])) for row in everyone)]) for name in names]
    values = [_value(name, width) for name, width in zip(names, widths, strict=True)]
    lines = text_table(results["rows"], [*values, *DESIGN_COLUMNS]).split("\n")
    for row in failed:
        cells = " ".join(f"{json.dumps(row[name]):>{width}s}" for name, width in zip(names, widths, strict=True))
        rate = "" if "successes" not in row else f" (labels: {row['successes']}/{row['trajectories']} successful)"
        lines.append(f"{cells} not analysed{rate}: {row['error']}")
    if results.get("correlations"):
        lines += ["", *_correlation_lines(results), "", *_convergence_lines(results)]
    return "\n".join(lines)


def _correlation_lines(results: dict[str, Any]) -> list[str]:
    lines = [f"Spearman rank correlation with the success rate ({len(results['rows'])} designs):"]
    for name in MARGINS:
        entry = results["correlations"][name]
        kind = "exact" if entry["exact"] else "permutation"
        interval = (
            "" if entry["low"] is None else f", 95 % trajectory bootstrap [{entry['low']:.2f}, {entry['high']:.2f}]"
        )
        p_value = "" if entry["p_value"] is None else f", p = {entry['p_value']:.3f} ({kind})"
        lines.append(f"  {MARGIN_LABELS[name]:>34s}: rho = {fmt(entry['rho'], 2)}{p_value}{interval}")
    return lines


def _convergence_lines(results: dict[str, Any]) -> list[str]:
    # The table as format_table lays it out, indented, without the rule under its titles.
    header, _rule, *body = text_table(results["convergence"], CONVERGENCE_COLUMNS).split("\n")
    title = "mean rho against the success rate of all trajectories, from t trajectories per design:"
    return [title, *(f"  {line}" for line in (header, *body))]
