"""What the robot does during a tree's propagation in robosuite's PickPlace: coasting, still, its recorded path.

Runs ``examples/robosuite_pick_place/pick_place.py`` once per hold of ``--holds`` (``coasting``,
``still``; ``--analysis hold``: the robot does the same in ``analyze``) with the same seeds
(``--seed`` and ``--env-seed``: the same episodes, the same live budget) in the robosuite stack's
interpreter (``--python``, e.g. ``.nox/stack-robosuite/bin/python``) on this checkout's code,
writing under ``WORK/HOLD``; a run whose ``results.json`` is already there is reused. Then the
entry ``recorded``: the coasting run's episodes recorded again with its scene file saying
``robot = "recorded"`` (what the example's default ``--analysis recorded`` writes), analysed and
evaluated the same way in the same interpreter under ``WORK/recorded`` (reused when its
``evaluate.json`` is there); its live scores are the coasting run's. Then one document: per
entry, ``evaluate``'s answers on the recorded episodes analysed by ``analyze`` (100 expansions)
and on the live scores, each question's verdict against the best baseline, the analysis's
seconds per frame and the live calls' expansions. The example's defaults (coasting live, the
recorded path in ``analyze``) were chosen on seed 1:

    python benchmarks/robosuite_hold.py --python .nox/stack-robosuite/bin/python --seed 1 --work runs/robosuite_hold \\
        --out docs/figures/robosuite_hold_seed1.json
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.scores_file import load_scores
from results_document import document_head, work_arguments, write_document
from stack_examples import questions

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples"))
from stack_common import summary as stack_summary

__all__ = ["HOLDS", "seconds_per_frame", "summary"]

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = "examples/robosuite_pick_place/pick_place.py"
#: The holds compared, in the document's order (then ``recorded``).
HOLDS = ("coasting", "still")
#: What the recorded entry's scene says in place of the coasting run's motion lines.
_COASTING_LINES = (
    "# The controller's torques are not known ahead: the robot keeps each frame's joint velocities.\n",
    'robot = "coasting"\n',
)
_RECORDED_LINES = (
    "# The controller's torques are not known ahead: the robot follows each episode's recorded joint path.\n",
    'robot = "recorded"\n',
)


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
                   "--hold", hold, "--analysis", "hold", "--no-picture", "--out", str(out)]  # fmt: skip
        with log.open("w", encoding="utf-8") as handle:
            subprocess.run(command, check=True, cwd=ROOT, env=_environment(), stdout=handle, stderr=subprocess.STDOUT)


def _environment() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}


def recorded_scene(coasting_scene: str) -> str:
    """The coasting run's scene file with its robot following each episode's recorded path in ``analyze``."""
    for old, new in zip(_COASTING_LINES, _RECORDED_LINES, strict=True):
        if old not in coasting_scene:
            raise ValueError(f"the coasting run's scene file has no line {old.strip()!r}")
        coasting_scene = coasting_scene.replace(old, new)
    return coasting_scene


def _recorded(python: Path, coasting: Path, out: Path) -> dict[str, Any]:
    """Record the coasting run's episodes again following their paths, analyse and evaluate them (reused when done)."""
    answers = out / "evaluate.json"
    if not answers.is_file():
        out.mkdir(parents=True, exist_ok=True)
        shutil.copy(coasting / "pick_place.xml", out / "pick_place.xml")
        (out / "scene.toml").write_text(recorded_scene((coasting / "scene.toml").read_text(encoding="utf-8")))
        results = json.loads((coasting / "results.json").read_text(encoding="utf-8"))
        frames = int(results["arguments"]["steps"]) // int(results["arguments"]["every"]) + 1
        episodes = sorted(str(path) for path in (coasting / "episodes").glob("episode_*.npz"))
        cli = [str(python), "-m", "energy_margin"]
        steps = (
            [*cli, "record", "--scene", str(out / "scene.toml"), *episodes, "--frames", str(frames), "--out",
             str(out / "dataset"), "--overwrite"],
            [*cli, "analyze", str(out / "dataset"), "--expansions", results["arguments"]["expansions"], "--workers",
             "1", "--no-progress"],
        )  # fmt: skip
        with (out.parent / f"{out.name}.log").open("w", encoding="utf-8") as handle:
            for command in steps:
                subprocess.run(
                    command, check=True, cwd=ROOT, env=_environment(), stdout=handle, stderr=subprocess.STDOUT
                )
        found = subprocess.run([*cli, "evaluate", str(out / "dataset"), "--json"], check=True, cwd=ROOT,
                               env=_environment(), capture_output=True, text=True)  # fmt: skip
        answers.write_text(found.stdout, encoding="utf-8")
    return json.loads(answers.read_text(encoding="utf-8"))


def seconds_per_frame(out: Path) -> float:
    """Mean wall time of a frame's analysis in the example's ``OUT/dataset``, s (what ``evaluate`` prints)."""
    return float(np.mean(load_scores(out / "dataset")["runtime_s"]))


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--python", type=Path, required=True, help="the robosuite stack's interpreter")
    parser.add_argument("--seed", type=int, default=1, help="the example's --seed and --env-seed")
    parser.add_argument(
        "--holds", default=",".join(HOLDS), help=f"the holds run, of {', '.join(HOLDS)} (coasting first)"
    )
    args = parser.parse_args()
    holds = tuple(args.holds.split(","))
    if not holds or holds[0] != "coasting" or not set(holds) <= set(HOLDS):
        parser.error(f"--holds: coasting, then others of {', '.join(HOLDS)}, got {args.holds!r}")
    document: dict[str, Any] = {**document_head("robosuite_hold.py"), "seed": args.seed, "holds": {}}
    for hold in holds:
        out = args.work.resolve() / hold
        _run(args.python, hold, args.seed, out)
        results = json.loads((out / "results.json").read_text(encoding="utf-8"))
        document["holds"][hold] = summary(results, seconds_per_frame(out))
        print(hold, {q: round(v["margin"], 3) for q, v in document["holds"][hold]["analyze"].items()}, flush=True)
    coasting, out = args.work.resolve() / "coasting", args.work.resolve() / "recorded"
    results = json.loads((coasting / "results.json").read_text(encoding="utf-8"))
    results["evaluate"] = {**results["evaluate"], "analyze": stack_summary(_recorded(args.python, coasting, out))}
    document["holds"]["recorded"] = summary(results, seconds_per_frame(out))
    print("recorded", {q: round(v["margin"], 3) for q, v in document["holds"]["recorded"]["analyze"].items()})
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
