"""Design search: black-box optimisation of a task's design by the energy margin, then verification.

``design_search`` searches the space of :mod:`~energy_margin.design.space` with an
optimiser of :mod:`~energy_margin.design.optimizers`. One evaluation of a design
generates T randomised roll-outs of F frames of it (``generate``), scores their frames (the tree of
``analyze`` at a budget of expansions, or a learned margin: the ``scorer``) and takes the mean over
the T trajectories of one score column (the success score by default). Every design is generated
and scored with the same seed: trajectory i of every design starts from the same draws and frame j
of it gets the same analysis seed (common random numbers), so designs differ by their setting, not
by luck.

After the search, the same objective is computed over the equal-cost grid (the even grid with as
many designs as the optimiser evaluated, at most) and for the task's own (default) design. The
verification then measures the real success rate of the chosen design (the search's best), the
default design and the grid's best, each over E closed-loop episodes per disturbance level
(``control``'s levels; the ``verifier``), with Wilson intervals; with ``verify_all`` every visited
design too, and Spearman's rho between the objective and the verified success rate over the
verified designs.

The verifier and the scorer are given by the caller (:class:`Scorer`, :class:`Verifier`): the
tree scorer lives here (:class:`TreeScorer`), the learned one in
:mod:`energy_margin.learning.scoring` and the episode verifier in
:mod:`energy_margin.design.verification`, stages after this one.

Layout of the output directory, a run directory (:func:`~energy_margin.runs.open_run`)::

    DIR/design.json              the resolved settings, written first (checked again on resume)
    DIR/evaluations/<design>/    each distinct evaluated design's roll-outs and scores
    DIR/evaluations.jsonl        journal: one line per evaluation (search, grid, default)
    DIR/verification.jsonl       journal: one line per verification episode
    DIR/result.json, result.csv  the verified designs (the JSON holds everything); evaluations.csv
    DIR/search.png, tool.png     the figure of the search and the picture of the chosen design

A rerun with the same settings replays the optimiser with the journal's objectives (the same
points, checked) and goes on where it stopped; the results do not depend on ``workers``.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.design.grid import Design
from energy_margin.design.optimizers import OPTIMIZERS, make_optimizer, require_optimizer
from energy_margin.design.rank import MARGIN_LABELS, MARGINS, design_outcome
from energy_margin.design.search_display import DesignSearchDisplay
from energy_margin.design.space import (
    check_models,
    compile_design,
    default_design,
    even_grid,
    grid_counts,
    parameter_dict,
    point_design,
    resolve_space,
    round_value,
)
from energy_margin.design.sweep import task_settings
from energy_margin.errors import EnergyMarginError, check_choice, check_int, check_seed
from energy_margin.evaluation.statistics import spearman, wilson_interval
from energy_margin.runs import Journal, RunSpec, progress_bar, run_directory
from energy_margin.runs.tables import Column, fmt, write_csv, write_json
from energy_margin.runs.tables import format_table as text_table
from energy_margin.tasks import DesignParameter, get_task

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

#: A design search's run directory. Every setting decides the results but the learned model's
#: path (its contents, by SHA-256, do).
DESIGN_RUN = RunSpec(
    contents="a design search",
    settings_file=SETTINGS_FILE,
    outputs=(
        EVALUATIONS_DIR,
        EVALUATIONS_JOURNAL,
        VERIFICATION_JOURNAL,
        RESULT_JSON,
        RESULT_CSV,
        EVALUATIONS_CSV,
        FIGURE_FILE,
        PICTURE_FILE,
    ),
    may_differ=("model_path",),
)


class Scorer(Protocol):
    """Scores every frame of a dataset directory: writes its ``scores.csv``."""

    def settings(self) -> dict[str, Any]:
        """What decides the scores (saved in ``design.json`` under ``objective``)."""

    def score(self, directory: Path, *, seed: int, workers: int) -> None:
        """Write ``scores.csv`` in ``directory`` (resuming what is there)."""


class Verifier(Protocol):
    """Runs closed-loop episodes of a design."""

    def settings(self) -> dict[str, Any]:
        """What decides the episodes besides design, level and seeds (saved under ``verify``)."""

    def check(self, task_name: str, levels: Sequence[str], *, fixed: dict[str, Any], n_objects: int) -> None:
        """Refuse a task, a scene or a level it cannot run, before anything is written."""

    def successes(
        self,
        task_name: str,
        overrides: dict[str, Any],
        *,
        n_objects: int,
        level: str,
        seeds: Sequence[tuple[int, np.random.SeedSequence]],
        workers: int = 1,
    ) -> Iterator[tuple[int, bool]]:
        """``(index, success)`` of each episode, in any order."""


@dataclass(frozen=True)
class TreeScorer:
    """The energy margin of ``analyze``: a tree of ``analyzer.iterations`` expansions per frame."""

    analyzer: AnalyzerConfig = field(default_factory=AnalyzerConfig)

    def settings(self) -> dict[str, Any]:
        """``{"kind": "margin", "analyzer": ...}``."""
        return {"kind": "margin", "analyzer": self.analyzer.to_dict()}

    def score(self, directory: Path, *, seed: int, workers: int) -> None:
        """``analyze`` the dataset (its journal resumes an interrupted analysis)."""
        analyze(directory, self.analyzer, seed=seed, workers=workers, progress=False)


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


def _directory_name(slug: str) -> str:
    """A design's folder under ``evaluations/``: its slug, or a digest of it when long."""
    if len(slug) <= 100:
        return slug
    return "design-" + hashlib.sha256(slug.encode("utf-8")).hexdigest()[:16]


def _label(values: dict[str, Any]) -> str:
    return ", ".join(f"{name}={json.dumps(value)}" for name, value in values.items())


# The search ---------------------------------------------------------------------------------------


@dataclass
class _Search:
    """A search under way: its settings, what it has measured and where it writes."""

    out: Path
    task: str
    space: list[DesignParameter]
    fixed: dict[str, Any]
    settings: dict[str, Any]
    scorer: Scorer
    verifier: Verifier | None
    workers: int
    progress: bool
    say: Callable[[str], None]
    on_evaluation: Callable[[str, int], None] | None
    measured: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def seed(self) -> int:
        return int(self.settings["seed"])

    def measure(self, design: Design) -> dict[str, Any]:
        """Generate, score and summarise one design (once per design: the same design gives the same value)."""
        cached = self.measured.get(design.slug)
        if cached is not None:
            return cached
        settings = self.settings
        directory = self.out / EVALUATIONS_DIR / _directory_name(design.slug)
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
                    f"{self.out / EVALUATIONS_JOURNAL}: evaluation {phase} {index} holds {_label(done['values'])} "
                    f"but the search now asks for {_label(values)}; pass --overwrite to start again"
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
        self.say(f"{prefix} {_label(values)}: {self.settings['objective']['score']} {objective}")
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
        self.say(f"design default {_label(design.values)}: {self.settings['objective']['score']} {objective}")
        if self.on_evaluation is not None:
            self.on_evaluation("default", 0)
        return row

    # Verification -----------------------------------------------------------------------------

    def verified_designs(
        self, search: list[dict[str, Any]], grid: list[dict[str, Any]], default: dict[str, Any]
    ) -> list[tuple[list[str], dict[str, Any]]]:
        """``(roles, evaluation)`` of each design to verify: chosen, default, grid best (then every visited one)."""
        chosen, grid_best = _best(search), _best(grid)
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
            entry = _entry(row, roles, verification.get(row["design"]), self.settings["verify"]["disturbances"])
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
            result["correlation"] = _correlations(entries, self.settings["verify"]["disturbances"], seed=self.seed)
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
        write_csv(self.out / RESULT_CSV, [_csv_row(entry) for entry in result["verified"]], _csv_fields(result, names))
        rows = [*result["search"], *result["grid_evaluations"], result["default_evaluation"]]
        fields = ["phase", "index", *names, "objective", "rollout_successes", "rollouts", "seconds", "error"]
        write_csv(self.out / EVALUATIONS_CSV, [{**row, **row["values"]} for row in rows], fields)
        if figure:
            DesignSearchDisplay.from_result(result).save(self.out / FIGURE_FILE)


#: Keys of an evaluation that describe the design's measurement (kept per design on resume).
_MEASURED = ("design", "objective", "error", "per_trajectory", "rollout_successes", "rollouts", "seconds")
_PHASES = ("search", "grid", "default")


def _best(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
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


def _entry(
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


def _correlations(entries: list[dict[str, Any]], levels: Sequence[str], *, seed: int) -> dict[str, Any]:
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


def _csv_fields(result: dict[str, Any], names: list[str]) -> list[str]:
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


def _csv_row(entry: dict[str, Any]) -> dict[str, Any]:
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


def format_result(result: dict[str, Any]) -> str:
    """The verified designs as a table, then what was searched and the rank correlation, as text."""
    settings = result["settings"]
    names = [p["name"] for p in settings["space"]]
    levels = list(settings["verify"]["disturbances"])
    score = settings["objective"]["score"]
    columns = [
        Column("design", _role, 8, "<"),
        *(Column(name, _value_cell(name), 8) for name in names),
        Column("objective", lambda e: fmt(e["objective"], 4), 9),
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
        return f"tree of {objective['analyzer']['iterations']} expansions a frame"
    return "learned margin"


# The entry point ----------------------------------------------------------------------------------


def design_search(
    task: str,
    params: Sequence[tuple[str, tuple[float, float] | list[Any]]] = (),
    *,
    optimizer: str = "tpe",
    evaluations: int,
    verify: int,
    out: Path | str,
    n_objects: int | None = None,
    n_trajectories: int = 4,
    n_frames: int = 6,
    seed: int = 0,
    score: str = "success_score",
    scorer: Scorer | None = None,
    verifier: Verifier | None = None,
    disturbances: Sequence[str] = DEFAULT_LEVELS,
    verify_all: bool = False,
    engine: str = "mujoco",
    fixed: dict[str, Any] | None = None,
    workers: int = 1,
    overwrite: bool = False,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
    picture: Callable[[Path, Path], Path | None] | None = None,
    extra_settings: dict[str, Any] | None = None,
    on_evaluation: Callable[[str, int], None] | None = None,
) -> dict[str, Any]:
    """Search the design of ``task`` by its energy margin, verify the result; write and return it.

    Every argument is checked, and the models of the space's corners compiled, before anything
    is written; the search then holds the lock of ``out`` until it returns.

    Args:
        task: a registered task (``"scene"`` with ``fixed={"scene_file": ...}`` for a scene file).
        params: ``(name, (low, high))`` or ``(name, [values])`` per axis
            (:func:`~energy_margin.design.params.parse_param`); empty: the
            task's tool family (:meth:`~energy_margin.tasks.base.Task.design_space`).
        optimizer: ``"cma"``, ``"tpe"`` or ``"grid"``.
        evaluations: the optimiser's evaluations N, >= 1 (the grid's at most N).
        verify: verification episodes E per design and disturbance level, >= 1.
        out: the run directory (a rerun with the same settings resumes it).
        n_objects: objects per scene (``None`` for a task that fixes them).
        n_trajectories: roll-outs T per evaluation, >= 1.
        n_frames: frames F per roll-out, >= 1.
        seed: generation and scoring seed of every design, the optimiser's seed and the
            verification episodes' (``SeedSequence(seed).spawn(verify)``).
        score: the score column whose mean over the T roll-outs is the objective
            (``success_score``, ``early_success_score`` or ``capture_score``).
        scorer: scores each design's frames (default :class:`TreeScorer` at 300 expansions).
        verifier: runs the verification episodes (``None``: no verification).
        disturbances: the levels of the verification.
        verify_all: verify every visited design too (for the rank correlation).
        engine: physics engine of generation and analysis.
        fixed: configuration overrides of every design (``--set``).
        workers: worker processes of each design's analysis and of the episodes, >= 1.
        overwrite: replace a search of other settings in ``out`` (its own files only).
        progress: show progress bars on standard error.
        log: receives one line per evaluation (standard error by default).
        picture: ``picture(dataset_directory, path)`` draws the chosen design (``tool.png``).
        extra_settings: more entries of ``design.json`` (``model_path``).
        on_evaluation: called with ``(phase, index)`` after each new evaluation is journalled.

    Returns:
        The contents of ``result.json``.

    Raises:
        EnergyMarginError: a bad argument, parameter, range, value or design (one line each),
            an optimiser whose library is missing, ``out`` holding something else.

    """
    check_int("evaluations", evaluations, minimum=1)
    check_int("verify", verify, minimum=1)
    check_int("n_trajectories", n_trajectories, minimum=1)
    check_int("n_frames", n_frames, minimum=1)
    check_seed(seed)
    check_int("workers", workers, minimum=1)
    check_choice("score", score, MARGINS)
    levels = list(dict.fromkeys(disturbances))
    if not levels:
        raise EnergyMarginError("the verification needs at least one disturbance level")
    fixed = dict(fixed or {})
    space = resolve_space(task, params, fixed=fixed)
    require_optimizer(optimizer, space)
    scorer = scorer if scorer is not None else TreeScorer()
    analyzer = scorer.analyzer if isinstance(scorer, TreeScorer) else None
    n_objects, analyzer = task_settings(get_task(task, fixed or None), n_objects, engine, analyzer)
    if isinstance(scorer, TreeScorer):
        scorer = TreeScorer(analyzer)
    if verifier is not None:
        verifier.check(task, levels, fixed=fixed, n_objects=n_objects)
    check_models(task, space, fixed, n_objects=n_objects, seed=seed, n_trajectories=n_trajectories)
    compile_design(
        task, default_design(task, space, fixed), n_objects=n_objects, seed=seed, n_trajectories=n_trajectories
    )
    used = evaluations if optimizer != "grid" else min(evaluations, math.prod(grid_counts(space, evaluations)))
    settings: dict[str, Any] = {
        "task": task,
        "fixed": fixed,
        "n_objects": n_objects,
        "n_trajectories": n_trajectories,
        "n_frames": n_frames,
        "seed": seed,
        "engine": engine,
        "space": [parameter_dict(parameter) for parameter in space],
        "optimizer": optimizer,
        "evaluations": evaluations,
        "objective": {**scorer.settings(), "score": score},
        "grid": {"counts": grid_counts(space, used), "size": math.prod(grid_counts(space, used))},
        "verify": {
            "episodes": verify,
            "disturbances": levels,
            "all": bool(verify_all),
            **(verifier.settings() if verifier is not None else {"policy": None}),
        },
        **(extra_settings or {}),
    }
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    with run_directory(out, DESIGN_RUN, settings, overwrite=overwrite, engine=engine) as run:
        search = _Search(
            run.path, task, space, fixed, run.settings, scorer, verifier, workers, progress, say, on_evaluation
        )
        result = search.run()
        chosen = result["chosen"]
        if picture is not None and chosen is not None:
            written = picture(run.path / EVALUATIONS_DIR / _directory_name(chosen["design"]), run.path / PICTURE_FILE)
            result["picture"] = None if written is None else PICTURE_FILE
            write_json(run.path / RESULT_JSON, result)
        return result


__all__ = [
    "DEFAULT_LEVELS",
    "DESIGN_RUN",
    "OPTIMIZERS",
    "PICTURE_FILE",
    "RESULT_JSON",
    "SETTINGS_FILE",
    "Scorer",
    "TreeScorer",
    "Verifier",
    "design_search",
    "format_result",
]
