"""One learned margin for 5, 10 and 20 pushed cylinders, against the tree on sets it never saw, and its speed.

The learned-margin tables of docs/howto/control.md, in one resumable run under ``--work``:

1. ``energy-margin learn --task pushing --objects 5,10,20 --trajectories 80 --frames 10 --holdout 0.1
   --seed 0`` generates, analyses (the defaults with the tree's own success score, as ``learn``
   does) and fits the set network;
2. ``energy-margin learn`` on the same three analysed sets with ``--kind boosting``;
3. three sets of generation seeds used for nothing else (5 objects, 40 trajectories, seed 41; 10, 40,
   31; 20, 30, 43), analysed as ``learn`` analyses (the tree's own success score, ``--continuation
   0``, else the defaults), seed 0;
4. ``bench_learned_ap.compare`` of both models on the three (APs with paired intervals, R²) and
   ``bench_learned.measure_dataset`` of the set network (per-query time, one process, one core,
   BLAS threads 1, beside 10 of the same frames' trees).

    python benchmarks/learned_margin.py --work runs/learned-margin --out docs/figures/learned_margin.json
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from typing import Any

from threadpoolctl import threadpool_limits

from bench_learned import measure_dataset
from bench_learned_ap import CAPTURE_WINDOWS, SUCCESS_SPANS, compare
from energy_margin.learning.margin_model import load_margin_model
from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["TEST_SETS", "cell", "table_rows"]

#: The sets the models never saw: name, objects, trajectories, generation seed.
TEST_SETS = (("push5c", 5, 40, 41), ("push10b", 10, 40, 31), ("push20c", 20, 30, 43))
QUESTIONS = (*CAPTURE_WINDOWS, *SUCCESS_SPANS)


def energy_margin(*arguments: str) -> str:
    """Run the command line in this interpreter; its standard output (exit on failure)."""
    command = [sys.executable, "-m", "energy_margin", *arguments]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-2000:]}")
    return done.stdout


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


def main() -> None:
    args = work_arguments(__doc__).parse_args()
    work, workers = args.work.resolve(), str(args.workers)
    work.mkdir(parents=True, exist_ok=True)
    document: dict[str, Any] = {**document_head("learned_margin.py"), "versions": engine_versions(), "steps": {}}
    set_model, boosting_model = work / "push_set.npz", work / "push_boosting.npz"
    learned, seconds = timed(
        "learn", "--task", "pushing", "--objects", "5,10,20", "--trajectories", "80", "--frames", "10",
        "--work", str(work / "push"), "--out", str(set_model), "--workers", workers, "--seed", "0",
        "--holdout", "0.1", "--json", "--overwrite",
    )  # fmt: skip
    document["steps"]["learn_set"] = {"wall_s": seconds, "result": json.loads(learned)}
    sets = [str(work / "push" / "sets" / f"objects-{n}") for n in (5, 10, 20)]
    learned, seconds = timed(
        "learn", *sets, "--out", str(boosting_model), "--kind", "boosting", "--holdout", "0.1", "--seed", "0",
        "--json", "--overwrite",
    )  # fmt: skip
    document["steps"]["learn_boosting"] = {"wall_s": seconds, "result": json.loads(learned)}
    tests = []
    for name, objects, trajectories, seed in TEST_SETS:
        path = work / name
        if not (path / "dataset.json").exists():
            energy_margin(
                "generate", "--task", "pushing", "--objects", str(objects), "--trajectories", str(trajectories),
                "--frames", "10", "--seed", str(seed), "--out", str(path),
            )  # fmt: skip
        _, seconds = timed("analyze", str(path), "--workers", workers, "--seed", "0", "--continuation", "0")
        document["steps"][f"analyze_{name}"] = {"wall_s": seconds}
        tests.append((name, objects, trajectories, seed, str(path)))
    rows = []
    for name, objects, _, seed, path in tests:
        for model in (set_model, boosting_model):
            row = compare(path, str(model), resamples=1000, seed=0)
            rows.append({"set": name, "n_objects": objects, "generation_seed": seed, **row})
    document["ap"] = rows
    document["table"] = table_rows(rows)
    write_document(args.out, document)
    model = load_margin_model(str(set_model))
    load_before = os.getloadavg()[0]
    with threadpool_limits(limits=1):
        speed = [measure_dataset(model, path, frames=1000, tree_frames=10, seed=0) for *_, path in tests]
    document["speed"] = {"load_before": load_before, "rows": speed}
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
