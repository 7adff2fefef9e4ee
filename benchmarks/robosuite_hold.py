"""What the robot does during a tree's propagation in robosuite's PickPlace: coasting against still.

Runs ``examples/robosuite_pick_place/pick_place.py`` once per ``--hold`` (``coasting``, ``still``)
with the same seeds (``--seed`` and ``--env-seed``: the same episodes, the same live budget) in the
robosuite stack's interpreter (``--python``, e.g. ``.nox/stack-robosuite/bin/python``) on this
checkout's code, writing under ``WORK/HOLD``; a run whose ``results.json`` is already there is
reused. Then one document: per hold, ``evaluate``'s answers on the recorded episodes analysed by
``analyze`` (100 expansions) and on the live scores, each question's verdict against the best
baseline, the analysis's seconds per frame and the live calls' expansions. The example's default
(coasting) was chosen on seed 1:

    python benchmarks/robosuite_hold.py --python .nox/stack-robosuite/bin/python --seed 1 --work runs/robosuite_hold \\
        --out docs/figures/robosuite_hold_seed1.json
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.scores_file import load_scores
from results_document import document_head, work_arguments, write_document
from stack_examples import questions

__all__ = ["HOLDS", "seconds_per_frame", "summary"]

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = "examples/robosuite_pick_place/pick_place.py"
#: The holds compared, in the document's order.
HOLDS = ("coasting", "still")


def summary(results: dict[str, Any], seconds_per_frame: float | None = None) -> dict[str, Any]:
    """The document's entry of one hold from the example's ``results.json`` and its analysis's time per frame, s."""
    return {
        "mujoco": results["mujoco"],
        "robosuite": results["robosuite"],
        "episodes": len(results["episodes"]),
        "success_rate": results["success_rate"],
        "live_mean_ms": results["timing"]["mean_ms"],
        "live_mean_expansions": results["timing"]["mean_expansions"],
        "analyze": questions({"evaluate": results["evaluate"]["analyze"]}),
        "live": questions({"evaluate": results["evaluate"]["live"]}),
        "seconds_per_frame": seconds_per_frame,
    }


def _run(python: Path, hold: str, seed: int, out: Path) -> None:
    """Run the example with ``hold`` into ``out`` (reused when done), its output into ``out``'s ``.log`` beside it."""
    log = out.parent / f"{out.name}.log"
    if not (out / "results.json").is_file():
        out.parent.mkdir(parents=True, exist_ok=True)
        command = [str(python), SCRIPT, "--episodes", "40", "--seed", str(seed), "--env-seed", str(seed),
                   "--hold", hold, "--no-picture", "--out", str(out)]  # fmt: skip
        environment = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
        with log.open("w", encoding="utf-8") as handle:
            subprocess.run(command, check=True, cwd=ROOT, env=environment, stdout=handle, stderr=subprocess.STDOUT)


def seconds_per_frame(out: Path) -> float:
    """Mean wall time of a frame's analysis in the example's ``OUT/dataset``, s (what ``evaluate`` prints)."""
    return float(np.mean(load_scores(out / "dataset")["runtime_s"]))


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--python", type=Path, required=True, help="the robosuite stack's interpreter")
    parser.add_argument("--seed", type=int, default=1, help="the example's --seed and --env-seed")
    args = parser.parse_args()
    document: dict[str, Any] = {**document_head("robosuite_hold.py"), "seed": args.seed, "holds": {}}
    for hold in HOLDS:
        out = args.work.resolve() / hold
        _run(args.python, hold, args.seed, out)
        results = json.loads((out / "results.json").read_text(encoding="utf-8"))
        document["holds"][hold] = summary(results, seconds_per_frame(out))
        print(hold, {q: round(v["margin"], 3) for q, v in document["holds"][hold]["analyze"].items()}, flush=True)
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
