"""Does the margin make manipulation more robust? Every policy on the same episodes: docs/howto/control.md's table.

In one resumable run under ``--work``:

1. the learned margins the ``learned`` policy uses: ``energy-margin learn --task pushing --objects
   5,10,20 --trajectories 80 --seed 0`` (the set network, ``push_set.npz``), boosted trees fitted on
   its 10-object set (``push10-boosting.npz``), and boosted trees fitted on ``learn --task scooping
   --trajectories 40 --seed 0`` (``scoop5-boosting.npz``);
2. ``energy-margin control`` for every cell of :data:`CELLS` (task, objects, disturbance, policy,
   model), each on the same episodes (``--seed 0``: the same starts, plant frictions, pushes and
   noise for every policy), ``--episodes`` of them (100), the default controller settings;
3. beside each cell's summary (success rate with its 95 % Wilson interval, captured frames, mean
   capture score), :func:`comparisons`: every policy against the script and the ``task`` policy of
   its group, and whether their intervals are apart.

Each cell is written to ``--out`` as soon as it is done; a cell already there is not run again
(``--cells`` names cells to run, ``--redo`` runs them again).

    python benchmarks/control_policies.py --work runs/control-policies --out docs/figures/control_policies.json
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from energy_margin.runs.versions import engine_versions
from results_document import document_head, energy_margin, work_arguments, write_document

__all__ = ["CELLS", "cell_name", "comparisons", "table_rows"]

ROOT = Path(__file__).resolve().parent.parent
PUSHING_SCENE = str(ROOT / "examples" / "pushing" / "pushing.toml")

#: (source, objects, disturbance, policy, model): ``source`` a task name or ``scene``; ``model`` one of
#: :data:`MODELS` or ``None``.
CELLS: tuple[tuple[str, int, str, str, str | None], ...] = (
    *(("pushing", 5, "hard", policy, model) for policy, model in (
        ("scripted", None), ("task", None), ("heuristic", None), ("margin", None),
        ("learned", "push10-boosting"), ("learned", "push_set"),
    )),
    *(("pushing", 5, "mild", policy, model) for policy, model in (
        ("scripted", None), ("task", None), ("heuristic", None), ("margin", None), ("learned", "push10-boosting"),
    )),
    *(("pushing", 10, "hard", policy, model) for policy, model in (
        ("scripted", None), ("task", None), ("heuristic", None), ("margin", None),
        ("learned", "push10-boosting"), ("learned", "push_set"),
    )),
    *(("pushing", 10, "mild", policy, model) for policy, model in (
        ("scripted", None), ("task", None), ("heuristic", None), ("margin", None), ("learned", "push10-boosting"),
    )),
    *(("scooping", 5, "hard", policy, model) for policy, model in (
        ("scripted", None), ("task", None), ("margin", None), ("learned", "scoop5-boosting"),
    )),
    ("scene", 10, "hard", "scripted", None),
    ("scene", 10, "hard", "task", None),
    ("scene", 10, "hard", "margin", None),
    *(("scooping", 5, "mild", policy, model) for policy, model in (
        ("scripted", None), ("task", None), ("margin", None), ("learned", "scoop5-boosting"),
    )),
)  # fmt: skip
MODELS = ("push_set", "push10-boosting", "scoop5-boosting")


def cell_name(source: str, objects: int, disturbance: str, policy: str, model: str | None) -> str:
    """``pushing5-hard-learned-push_set``: the cell's key in the document and its run folder."""
    return f"{source}{objects}-{disturbance}-{policy}" + (f"-{model}" if model else "")


def fit_models(work: Path, workers: str) -> dict[str, Any]:
    """The three learned margins under ``work``, each fitted once; what each ``learn`` printed."""
    fitted: dict[str, Any] = {}
    steps = {
        "push_set": ("learn", "--task", "pushing", "--objects", "5,10,20", "--trajectories", "80", "--seed", "0",
                     "--frames", "10", "--work", str(work / "learn-pushing"), "--workers", workers),
        "push10-boosting": ("learn", str(work / "learn-pushing" / "sets" / "objects-10"), "--kind", "boosting",
                            "--seed", "0"),
        "scoop5-set": ("learn", "--task", "scooping", "--trajectories", "40", "--seed", "0", "--frames", "10",
                       "--work", str(work / "learn-scooping"), "--workers", workers),
        "scoop5-boosting": ("learn", str(work / "learn-scooping" / "sets" / "objects-5"), "--kind", "boosting",
                            "--seed", "0"),
    }  # fmt: skip
    for name, arguments in steps.items():
        model, record = work / f"{name}.npz", work / f"{name}.json"
        if not record.exists():
            started = time.perf_counter()
            printed = energy_margin(*arguments, "--out", str(model), "--holdout", "0.1", "--json", "--overwrite")
            step = {"wall_s": time.perf_counter() - started, "result": json.loads(printed)}
            record.write_text(json.dumps(step), encoding="utf-8")
        fitted[name] = json.loads(record.read_text(encoding="utf-8"))
    return fitted


def run_cell(cell: tuple[str, int, str, str, str | None], work: Path, episodes: int, workers: str) -> dict[str, Any]:
    """One cell's ``control`` run (replacing an earlier one): its summary, wall time and load."""
    source, objects, disturbance, policy, model = cell
    where = ("--scene", PUSHING_SCENE) if source == "scene" else ("--task", source, "--objects", str(objects))
    arguments = [
        "control", *where, "--episodes", str(episodes), "--policy", policy, "--disturbance", disturbance,
        "--seed", "0", "--out", str(work / "control" / cell_name(*cell)), "--workers", workers,
        "--overwrite", "--no-progress", "--json",
    ]  # fmt: skip
    if model:
        arguments += ["--model", str(work / f"{model}.npz")]
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    summary = json.loads(energy_margin(*arguments))
    return {
        "source": source, "objects": objects, "disturbance": disturbance, "policy": policy, "model": model,
        "wall_s": time.perf_counter() - started, "load_before": load_before, "summary": summary,
    }  # fmt: skip


def _policy_label(entry: dict[str, Any]) -> str:
    return f"`{entry['policy']}`" + (", set network" if entry["model"] == "push_set" else "")


def table_rows(cells: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The table's rows in :data:`CELLS` order, for the cells measured."""
    rows = []
    for cell in CELLS:
        entry = cells.get(cell_name(*cell))
        if entry is None:
            continue
        summary = entry["summary"]
        low, high = summary["success_interval"]
        rows.append({
            "task": "scene file (examples/pushing)" if entry["source"] == "scene" else entry["source"],
            "objects": summary["n_objects"], "disturbance": entry["disturbance"], "policy": _policy_label(entry),
            "episodes": summary["episodes"], "success": summary["success_rate"], "low": low, "high": high,
            "captured": summary["captured_fraction"], "capture_score": summary["mean_capture_score"],
        })  # fmt: skip
    return rows


def comparisons(cells: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Every policy against the script and ``task`` of its group: difference and whether the intervals are apart."""
    found = []
    for cell in CELLS:
        entry = cells.get(cell_name(*cell))
        if entry is None or entry["policy"] in ("scripted",):
            continue
        source, objects, disturbance = cell[:3]
        for against in ("scripted", "task"):
            other = cells.get(cell_name(source, objects, disturbance, against, None))
            if other is None or other is entry:
                continue
            mine, theirs = entry["summary"], other["summary"]
            apart = (
                mine["success_interval"][0] > theirs["success_interval"][1]
                or mine["success_interval"][1] < theirs["success_interval"][0]
            )
            found.append({
                "task": "scene file" if source == "scene" else source, "objects": objects,
                "disturbance": disturbance, "policy": _policy_label(entry), "against": f"`{against}`",
                "difference": mine["success_rate"] - theirs["success_rate"],
                "verdict": "significant" if apart else "intervals overlap",
            })  # fmt: skip
    return found


def main() -> None:
    parser = work_arguments(__doc__)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--cells", nargs="+", default=None, help="cell names to run (default: every cell)")
    parser.add_argument("--redo", action="store_true", help="run the named cells again")
    args = parser.parse_args()
    work, workers = args.work.resolve(), str(args.workers)
    work.mkdir(parents=True, exist_ok=True)
    kept = json.loads(args.out.read_text(encoding="utf-8")) if args.out.exists() else {}
    document: dict[str, Any] = {
        **document_head("control_policies.py"),
        "versions": engine_versions(),
        "episodes": args.episodes,
        "models": fit_models(work, workers),
        "cells": kept.get("cells", {}),
    }
    for cell in CELLS:
        name = cell_name(*cell)
        if (args.cells and name not in args.cells) or (name in document["cells"] and not args.redo):
            continue
        document["cells"][name] = run_cell(cell, work, args.episodes, workers)
        document["table"] = table_rows(document["cells"])
        document["comparisons"] = comparisons(document["cells"])
        write_document(args.out, document)
        summary = document["cells"][name]["summary"]
        print(f"{name}: success {summary['success_rate']:.2f} in {document['cells'][name]['wall_s']:.0f} s")


if __name__ == "__main__":
    main()
