"""``calibrate`` on one example's trajectories: λ alone, then λ with the wrench scales (``--grow``).

Generates a set of a scene file (the Jaco example, 30 trajectories × 10 frames, generation seed 77
by default: used for nothing else), then runs ``energy-margin calibrate`` on it twice with two
workers, each in a fresh run directory under ``--work``: the default λ grid and objective, and the
same with ``--wrench-scales 0.5 1 2 --duration-scales 1``. The document keeps each run's JSON
(held-out APs, each fold's choice, the baselines and the paired verdicts) with its wall time and
the load average before it:

    python benchmarks/calibrate_example.py --work runs/calibrate-example --out docs/figures/calibrate_jaco.json
"""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

from energy_margin.runs.versions import engine_versions
from results_document import document_head, energy_margin, work_arguments, write_document

__all__ = ["RUNS", "calibrate"]

ROOT = Path(__file__).resolve().parent.parent
#: The two runs: a name and the options they add to ``calibrate``.
RUNS: dict[str, list[str]] = {
    "lambda": [],
    "grow": ["--wrench-scales", "0.5", "1", "2", "--duration-scales", "1"],
}


def calibrate(dataset: Path, out: Path, options: list[str], *, workers: int, seed: int) -> dict[str, Any]:
    """One fresh ``calibrate`` run of ``dataset`` into ``out``: its JSON, wall time and load before."""
    shutil.rmtree(out, ignore_errors=True)
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    printed = energy_margin(
        "calibrate", str(dataset), "--out", str(out), "--workers", str(workers), "--seed", str(seed), "--json", *options
    )
    wall = time.perf_counter() - started
    return {"options": options, "wall_s": wall, "load_before": load_before, "result": json.loads(printed)}


def main() -> None:
    parser = work_arguments(__doc__)
    parser.add_argument("--scene", type=Path, default=ROOT / "examples/jaco/jaco.toml")
    parser.add_argument("--trajectories", type=int, default=30)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--generation-seed", type=int, default=77)
    parser.add_argument("--seed", type=int, default=0, help="the analyses' seed")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    dataset = args.work / "set"
    if not (dataset / "dataset.json").exists():
        energy_margin(
            "generate", "--scene", str(args.scene), "--trajectories", str(args.trajectories), "--frames",
            str(args.frames), "--seed", str(args.generation_seed), "--out", str(dataset),
        )  # fmt: skip
    document: dict[str, Any] = {
        **document_head("calibrate_example.py"),
        "versions": engine_versions(),
        "settings": {
            "scene": str(args.scene.resolve().relative_to(ROOT))
            if args.scene.resolve().is_relative_to(ROOT)
            else str(args.scene),
            "trajectories": args.trajectories,
            "frames": args.frames,
            "generation_seed": args.generation_seed,
            "seed": args.seed,
            "workers": args.workers,
        },
        "runs": {},
    }
    for name, options in RUNS.items():
        run = calibrate(dataset, args.work / name, options, workers=args.workers, seed=args.seed)
        document["runs"][name] = run
        chosen = run["result"]["likelihood_lambda"]
        print(f"{name}: lambda {chosen} in {run['wall_s']:.0f} s (load before {run['load_before']:.2f})")
        write_document(args.out, document)


if __name__ == "__main__":
    main()
