"""Learned margins against the tree on sets they never saw, and their speed: the tables of docs/howto/control.md.

Each study, in one resumable run under ``--work/NAME``:

1. ``energy-margin learn`` in its generating form (``--task`` or ``--scene``, ``--holdout 0.1``)
   generates, analyses (the defaults with the tree's own success score, as ``learn`` does) and fits
   the set network;
2. ``energy-margin learn`` on the same analysed sets with ``--kind boosting``;
3. sets of generation seeds used for nothing else, analysed as ``learn`` analyses
   (``--continuation 0``), seed 0;
4. ``bench_learned_ap.compare`` of both models on them (APs with paired intervals, R²) and, for the
   pushing study, ``bench_learned.measure_dataset`` of the set network (per-query time, one process,
   one core, BLAS threads 1, beside 10 of the same frames' trees).

The studies (:data:`STUDIES`): ``pushing`` (one model for 5, 10 and 20 cylinders, 80 trajectories
each, seed 0; scored on 5 objects × 40 trajectories of seed 41, 10 × 40 of seed 31, 20 × 30 of seed
43), ``scooping`` (80 trajectories, seed 0; 30 of seed 34), and the example scene files
``pushing_scene`` (108 trajectories, seed 5) and ``jaco`` (72, seed 5), each scored on 30
trajectories of seed 77. A study run again replaces its own entry of ``--out`` only.

    python benchmarks/learned_margin.py --work runs/learned-margin --out docs/figures/learned_margin.json

(``--studies S ...`` runs some of them.)
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from threadpoolctl import threadpool_limits

from bench_learned import measure_dataset
from bench_learned_ap import CAPTURE_WINDOWS, SUCCESS_SPANS, compare
from energy_margin.learning.margin_model import load_margin_model
from energy_margin.runs.versions import engine_versions
from results_document import document_head, energy_margin, work_arguments, write_document

__all__ = ["STUDIES", "Study", "cell", "run_study", "table_rows"]

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Study:
    """One learned margin: what ``learn`` generates and fits, and the sets it never saw."""

    #: ``learn``'s source options (``--task``/``--scene``, ``--objects``, ``--trajectories``, ``--seed``).
    learn: tuple[str, ...]
    #: The analysed sets under ``WORK/NAME/sets`` that the boosted trees are fitted on.
    sets: tuple[str, ...]
    #: The sets it never saw: name and ``generate``'s source options.
    tests: tuple[tuple[str, tuple[str, ...]], ...]
    #: Whether to time the set network's queries beside the tree.
    speed: bool = False


def _scene(name: str) -> str:
    return str(ROOT / "examples" / name / f"{name}.toml")


STUDIES: dict[str, Study] = {
    "pushing": Study(
        ("--task", "pushing", "--objects", "5,10,20", "--trajectories", "80", "--seed", "0"),
        ("objects-5", "objects-10", "objects-20"),
        (
            ("push5c", ("--task", "pushing", "--objects", "5", "--trajectories", "40", "--seed", "41")),
            ("push10b", ("--task", "pushing", "--objects", "10", "--trajectories", "40", "--seed", "31")),
            ("push20c", ("--task", "pushing", "--objects", "20", "--trajectories", "30", "--seed", "43")),
        ),
        speed=True,
    ),
    "scooping": Study(
        ("--task", "scooping", "--trajectories", "80", "--seed", "0"),
        ("objects-5",),
        (("scoop5c", ("--task", "scooping", "--objects", "5", "--trajectories", "30", "--seed", "34")),),
    ),
    "pushing_scene": Study(
        ("--scene", _scene("pushing"), "--trajectories", "108", "--seed", "5"),
        ("scene",),
        (("pushing77", ("--scene", _scene("pushing"), "--trajectories", "30", "--seed", "77")),),
    ),
    "jaco": Study(
        ("--scene", _scene("jaco"), "--trajectories", "72", "--seed", "5"),
        ("scene",),
        (("jaco77", ("--scene", _scene("jaco"), "--trajectories", "30", "--seed", "77")),),
    ),
}
QUESTIONS = (*CAPTURE_WINDOWS, *SUCCESS_SPANS)


def cell(entry: dict[str, Any] | None) -> str:
    """``0.990 / 0.988 (+0.002 [−0.004, +0.009])``: learned / tree (difference [paired interval])."""
    if entry is None or entry["learned"] is None:
        return "–"
    if entry["low"] is None:
        return f"{entry['learned']:.3f} / {entry['tree']:.3f}"
    return (
        f"{entry['learned']:.3f} / {entry['tree']:.3f} "
        f"({entry['difference']:+.3f} [{entry['low']:+.3f}, {entry['high']:+.3f}])"
    )


def table_rows(rows: list[dict[str, Any]]) -> list[dict[str, str]]:
    """The cells of the table: one row per set and model, the questions as ``q0``, ``q1``, …."""
    table = []
    for row in rows:
        r2 = " / ".join("–" if value is None else f"{value:.3f}" for value in (row["r2_capture"], row["r2_success"]))
        cells = {f"q{i}": cell(row["questions"].get(name)) for i, name in enumerate(QUESTIONS)}
        table.append({"set": row["set"], "model": row["kind"], **cells, "r2": r2})
    return table


def timed(*arguments: str) -> tuple[str, float]:
    """A command's output and wall seconds."""
    started = time.perf_counter()
    printed = energy_margin(*arguments)
    return printed, time.perf_counter() - started


def run_study(study: Study, work: Path, workers: str) -> dict[str, Any]:
    """One study under ``work``: its steps' wall times and results, the comparisons, their table, the speed."""
    work.mkdir(parents=True, exist_ok=True)
    entry: dict[str, Any] = {"steps": {}}
    set_model, boosting_model = work / "set.npz", work / "boosting.npz"
    learned, seconds = timed(
        "learn", *study.learn, "--frames", "10", "--work", str(work / "learn"), "--out", str(set_model),
        "--workers", workers, "--holdout", "0.1", "--json", "--overwrite",
    )  # fmt: skip
    entry["steps"]["learn_set"] = {"wall_s": seconds, "result": json.loads(learned)}
    sets = [str(work / "learn" / "sets" / name) for name in study.sets]
    learned, seconds = timed(
        "learn", *sets, "--out", str(boosting_model), "--kind", "boosting", "--holdout", "0.1", "--seed", "0",
        "--json", "--overwrite",
    )  # fmt: skip
    entry["steps"]["learn_boosting"] = {"wall_s": seconds, "result": json.loads(learned)}
    rows = []
    for name, source in study.tests:
        path = work / name
        if not (path / "dataset.json").exists():
            energy_margin("generate", *source, "--frames", "10", "--out", str(path))
        _, seconds = timed("analyze", str(path), "--workers", workers, "--seed", "0", "--continuation", "0")
        entry["steps"][f"analyze_{name}"] = {"wall_s": seconds}
        for model in (set_model, boosting_model):
            rows.append({"set": name, **compare(str(path), str(model), resamples=1000, seed=0)})
    entry["ap"] = rows
    entry["table"] = table_rows(rows)
    if study.speed:
        model = load_margin_model(str(set_model))
        load_before = os.getloadavg()[0]
        with threadpool_limits(limits=1):
            speed = [
                measure_dataset(model, str(work / name), frames=1000, tree_frames=10, seed=0) for name, _ in study.tests
            ]
        entry["speed"] = {"load_before": load_before, "rows": speed}
    return entry


def main() -> None:
    parser = work_arguments(__doc__)
    parser.add_argument("--studies", nargs="+", choices=list(STUDIES), default=list(STUDIES))
    args = parser.parse_args()
    work, workers = args.work.resolve(), str(args.workers)
    kept = json.loads(args.out.read_text(encoding="utf-8")) if args.out.exists() else {}
    document: dict[str, Any] = {
        **document_head("learned_margin.py"),
        "versions": engine_versions(),
        "studies": kept.get("studies", {}),
    }
    for name in args.studies:
        document["studies"][name] = run_study(STUDIES[name], work / name, workers)
        write_document(args.out, document)
        print(f"{name}: written to {args.out}")


if __name__ == "__main__":
    main()
