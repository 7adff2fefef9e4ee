"""A design search under way: its evaluations journalled, its best designs verified, its results written.

:class:`DesignSearchRun` is what :func:`~energy_margin.design.search.design_search` runs once its
arguments are checked and its run directory is open: the optimiser's evaluations, the equal-cost
grid's and the default design's (each journalled in ``evaluations.jsonl`` and read back on
resume), the verification episodes (``verification.jsonl``) and ``result.json``, ``result.csv``,
``evaluations.csv`` and the figure.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.design.grid import Design, design_label
from energy_margin.design.optimizers import make_optimizer
from energy_margin.design.rank import design_outcome
from energy_margin.design.scorers import Scorer, Verifier
from energy_margin.design.search_display import DesignSearchDisplay
from energy_margin.design.search_result import (
    best_evaluation,
    objective_correlations,
    result_csv_fields,
    result_csv_row,
    verified_entry,
)
from energy_margin.design.space import default_design, even_grid, point_design, round_value
from energy_margin.errors import EnergyMarginError
from energy_margin.runs import Journal, progress_bar
from energy_margin.runs.progress import Progress
from energy_margin.runs.tables import write_csv, write_json
from energy_margin.tasks import DesignParameter, Task

__all__ = ["DesignSearchRun", "directory_name"]

SETTINGS_FILE = "design.json"
EVALUATIONS_DIR = "evaluations"
EVALUATIONS_JOURNAL = "evaluations.jsonl"
VERIFICATION_JOURNAL = "verification.jsonl"
RESULT_JSON = "result.json"
RESULT_CSV = "result.csv"
EVALUATIONS_CSV = "evaluations.csv"
FIGURE_FILE = "search.png"
PICTURE_FILE = "tool.png"
#: The disturbance levels of the verification by default (``control --disturbance``).
DEFAULT_LEVELS = ("mild", "hard")
#: The objective a failed evaluation tells the optimiser: the least any score takes.
FAILED_OBJECTIVE = 0.0


# Journals ---------------------------------------------------------------------------------------


def _parse(line: str) -> dict[str, Any] | None:
    try:
        row = json.loads(line)
    except json.JSONDecodeError:
        return None
    return row if isinstance(row, dict) else None


def _journal(path: Path, header: str, key: Callable[[dict[str, Any]], Any]) -> Journal[Any]:
    return Journal(
        path,
        header=f"# energy-margin design: {header}\n",
        format_row=lambda row: json.dumps(row, sort_keys=True),
        parse_row=_parse,
        key=key,
    )


def _plain(value: Any) -> Any:
    return json.loads(json.dumps(value))


def directory_name(slug: str) -> str:
    """A design's folder under ``evaluations/``: its slug, or a digest of it when long."""
    if len(slug) <= 100:
        return slug
    return "design-" + hashlib.sha256(slug.encode("utf-8")).hexdigest()[:16]


# The search ---------------------------------------------------------------------------------------


@dataclass
class DesignSearchRun:
    """A search under way: its settings, what it has measured and where it writes."""

    out: Path
    task: Task
    space: list[DesignParameter]
    fixed: dict[str, Any]
    settings: dict[str, Any]
    scorer: Scorer
    verifier: Verifier | None
    workers: int
    progress: Progress
    say: Callable[[str], None]
    on_evaluation: Callable[[str, int], None] | None
    measured: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def seed(self) -> int:
        """The seed of every design's generation and scoring."""
        return int(self.settings["seed"])

    def measure(self, design: Design) -> dict[str, Any]:
        """Generate, score and summarise one design (once per design: the same design gives the same value)."""
        cached = self.measured.get(design.slug)
        if cached is not None:
            return cached
        settings = self.settings
        directory = self.out / EVALUATIONS_DIR / directory_name(design.slug)
        started = time.perf_counter()
        result: dict[str, Any] = {"design": design.slug, "objective": None, "error": None}
        try:
            generate_dataset(
                self.task,
                n_objects=settings["n_objects"],
                n_trajectories=settings["n_trajectories"],
                n_frames=settings["n_frames"],
                seed=self.seed,
                out=directory,
                engine=settings["engine"],
                task_config=design.overrides,
            )
            self.scorer.score(directory, seed=self.seed, workers=self.workers)
            outcome = design_outcome(load_dataset(directory), load_scores(directory))
        except EnergyMarginError as error:
            # A design whose roll-outs cannot be generated or scored (its model does not
            # compile, the analysis's checks refuse its frames) is a failed evaluation.
            result["error"] = " ".join(str(error).split())
        else:
            values = outcome.column(settings["objective"]["score"])
            result.update(
                objective=float(values.mean()),
                per_trajectory=values.tolist(),
                rollout_successes=int(outcome.success.sum()),
                rollouts=int(outcome.success.size),
            )
        result["seconds"] = time.perf_counter() - started
        self.measured[design.slug] = result
        return result

    def _design(self, point: Sequence[Any]) -> tuple[Design | None, dict[str, Any], str | None]:
        values = {p.name: round_value(p, v) for p, v in zip(self.space, point, strict=True)}
        try:
            return point_design(self.task, self.space, list(values.values()), self.fixed), values, None
        except EnergyMarginError as error:
            return None, values, " ".join(str(error).split())

    def evaluate(
        self,
        phase: str,
        index: int,
        point: Sequence[Any],
        journal: Journal[Any],
        stored: dict[Any, dict[str, Any]],
        bar: Any,
        prefix: str,
    ) -> dict[str, Any]:
        """One evaluation of the journal (read back when it is there, its point checked)."""
        design, values, invalid = self._design(point)
        done = stored.get((phase, index))
        if done is not None:
            if _plain(done["values"]) != _plain(values):
                raise EnergyMarginError(
                    f"{self.out / EVALUATIONS_JOURNAL}: evaluation {phase} {index} holds "
                    f"{design_label(done['values'])} but the search now asks for {design_label(values)}; "
                    "pass `overwrite=True` to start again"
                )
            if design is not None and done["objective"] is not None:
                self.measured.setdefault(design.slug, {key: done[key] for key in _MEASURED if key in done})
            return done
        if design is None:
            row: dict[str, Any] = {"design": None, "objective": None, "error": invalid, "seconds": 0.0}
        else:
            row = dict(self.measure(design))
        row.update(phase=phase, index=index, values=values)
        journal.append(row)
        bar.update(1)
        objective = "failed: " + str(row["error"]) if row["objective"] is None else f"{row['objective']:.4f}"
        self.say(f"{prefix} {design_label(values)}: {self.settings['objective']['score']} {objective}")
        if self.on_evaluation is not None:
            self.on_evaluation(phase, index)
        return row

    def run(self) -> dict[str, Any]:
        """The search, the grid, the default design, the verification; the results (written)."""
        settings = self.settings
        journal = _journal(self.out / EVALUATIONS_JOURNAL, "evaluations", lambda row: (row["phase"], row["index"]))
        stored = journal.read()
        journal.rewrite(stored, order=sorted(stored, key=lambda key: (_PHASES.index(key[0]), key[1])))
        budget = int(settings["evaluations"])
        optimizer = make_optimizer(settings["optimizer"], self.space, budget=budget, seed=self.seed)
        used = min(budget, optimizer.limit or budget)
        grid = even_grid(self.space, used)
        total = used + len(grid) + 1
        bar = progress_bar(total, desc="design", unit="design", initial=len(stored), enabled=self.progress)
        search: list[dict[str, Any]] = []
        grid_rows: list[dict[str, Any]] = []
        try:
            with journal:
                for index in range(used):
                    point = optimizer.ask()
                    row = self.evaluate(
                        "search",
                        index,
                        point,
                        journal,
                        stored,
                        bar,
                        f"design {settings['optimizer']} [{index + 1}/{used}]",
                    )
                    optimizer.tell(FAILED_OBJECTIVE if row["objective"] is None else row["objective"])
                    search.append(row)
                for index, point in enumerate(grid):
                    prefix = f"design grid [{index + 1}/{len(grid)}]"
                    grid_rows.append(self.evaluate("grid", index, point, journal, stored, bar, prefix))
                default = self._default(journal, stored, bar)
        finally:
            bar.close()
        result = self.summarize(search, grid_rows, default, verification={})
        self.write(result, figure=False)
        verification = self.verify(result)
        result = self.summarize(search, grid_rows, default, verification=verification)
        self.write(result)
        return result

    def _default(self, journal: Journal[Any], stored: dict[Any, dict[str, Any]], bar: Any) -> dict[str, Any]:
        design = default_design(self.task, self.space, self.fixed)
        done = stored.get(("default", 0))
        if done is not None:
            return done
        row = dict(self.measure(design))
        row.update(phase="default", index=0, values=design.values)
        journal.append(row)
        bar.update(1)
        objective = "failed: " + str(row["error"]) if row["objective"] is None else f"{row['objective']:.4f}"
        self.say(f"design default {design_label(design.values)}: {self.settings['objective']['score']} {objective}")
        if self.on_evaluation is not None:
            self.on_evaluation("default", 0)
        return row

    # Verification -----------------------------------------------------------------------------

    def verified_designs(
        self, search: list[dict[str, Any]], grid: list[dict[str, Any]], default: dict[str, Any]
    ) -> list[tuple[list[str], dict[str, Any]]]:
        """``(roles, evaluation)`` of each design to verify: chosen, default, grid best (then every visited one)."""
        chosen, grid_best = best_evaluation(search), best_evaluation(grid)
        entries: list[tuple[list[str], dict[str, Any]]] = []
        by_design: dict[str, list[str]] = {}

        def add(role: str | None, row: dict[str, Any] | None) -> None:
            if row is None or row["design"] is None:
                return
            if row["design"] in by_design:
                if role is not None and role not in by_design[row["design"]]:
                    by_design[row["design"]].append(role)
                return
            roles = [] if role is None else [role]
            by_design[row["design"]] = roles
            entries.append((roles, row))

        add("chosen", chosen)
        add("default", default)
        add("grid", grid_best)
        if self.settings["verify"]["all"]:
            for row in [*search, *grid]:
                if row["objective"] is not None:
                    add(None, row)
        return entries

    def verify(self, result: dict[str, Any]) -> dict[str, dict[str, list[bool]]]:
        """The verification episodes of every design to verify: ``{design: {level: successes}}``."""
        if self.verifier is None:
            return {}
        verify = self.settings["verify"]
        episodes, levels = int(verify["episodes"]), list(verify["disturbances"])
        targets = [(entry["design"], entry["task_config"]) for entry in result["verified"]]
        journal = _journal(
            self.out / VERIFICATION_JOURNAL, "verification", lambda row: (row["design"], row["level"], row["episode"])
        )
        stored = journal.read()
        journal.rewrite(stored)
        total = len(targets) * len(levels) * episodes
        bar = progress_bar(total, desc="verify", unit="episode", initial=len(stored), enabled=self.progress)
        outcome: dict[str, dict[str, list[bool]]] = {}
        try:
            with journal:
                for slug, overrides in targets:
                    for level in levels:
                        done = {
                            i: bool(stored[(slug, level, i)]["success"])
                            for i in range(episodes)
                            if (slug, level, i) in stored
                        }
                        # Fresh sequences for every design and level (an episode spawns from its own,
                        # which changes it): episode i is control's episode i of --seed.
                        seeds = np.random.SeedSequence(self.seed).spawn(episodes)
                        jobs = [(i, seeds[i]) for i in range(episodes) if i not in done]
                        for index, success in self.verifier.successes(
                            self.task,
                            overrides,
                            n_objects=self.settings["n_objects"],
                            level=level,
                            seeds=jobs,
                            workers=self.workers,
                        ):
                            journal.append({"design": slug, "level": level, "episode": index, "success": success})
                            done[index] = success
                            bar.update(1)
                        outcome.setdefault(slug, {})[level] = [done[i] for i in range(episodes)]
                        rate = sum(done.values()) / episodes
                        self.say(f"design verify {slug} {level}: success {sum(done.values())}/{episodes} ({rate:.2f})")
        finally:
            bar.close()
        return outcome

    # Results ----------------------------------------------------------------------------------

    def summarize(
        self,
        search: list[dict[str, Any]],
        grid: list[dict[str, Any]],
        default: dict[str, Any],
        *,
        verification: dict[str, dict[str, list[bool]]],
    ) -> dict[str, Any]:
        """The contents of ``result.json``."""
        entries = []
        for roles, row in self.verified_designs(search, grid, default):
            entry = verified_entry(row, roles, verification.get(row["design"]), self.settings["verify"]["disturbances"])
            entry["task_config"] = self._overrides(row)
            entries.append(entry)
        by_role = {role: entry for entry in entries for role in entry["roles"]}
        result: dict[str, Any] = {
            "settings": self.settings,
            "chosen": by_role.get("chosen"),
            "default": by_role.get("default"),
            "grid": by_role.get("grid"),
            "verified": entries,
            "search": search,
            "grid_evaluations": grid,
            "default_evaluation": default,
            "evaluations_used": len(search),
            "grid_size": len(grid),
            "margin_evaluations": len({row["design"] for row in [*search, *grid, default] if row["design"]}),
        }
        if verification:
            result["correlation"] = objective_correlations(
                entries, self.settings["verify"]["disturbances"], seed=self.seed
            )
        return result

    def _overrides(self, row: dict[str, Any]) -> dict[str, Any]:
        if row["phase"] == "default":
            return dict(self.fixed)
        # By name: a journal row's values come back in the journal's (sorted) key order.
        design = point_design(self.task, self.space, [row["values"][p.name] for p in self.space], self.fixed)
        return design.overrides

    def write(self, result: dict[str, Any], *, figure: bool = True) -> None:
        """``result.json``, ``result.csv``, ``evaluations.csv`` and the figure (with matplotlib)."""
        names = [p.name for p in self.space]
        write_json(self.out / RESULT_JSON, result)
        write_csv(
            self.out / RESULT_CSV,
            [result_csv_row(entry) for entry in result["verified"]],
            result_csv_fields(result, names),
        )
        rows = [*result["search"], *result["grid_evaluations"], result["default_evaluation"]]
        fields = ["phase", "index", *names, "objective", "rollout_successes", "rollouts", "seconds", "error"]
        write_csv(self.out / EVALUATIONS_CSV, [{**row, **row["values"]} for row in rows], fields)
        if figure:
            DesignSearchDisplay.from_result(result).save(self.out / FIGURE_FILE)


#: Keys of an evaluation that describe the design's measurement (kept per design on resume).
_MEASURED = ("design", "objective", "error", "per_trajectory", "rollout_successes", "rollouts", "seconds")
_PHASES = ("search", "grid", "default")
