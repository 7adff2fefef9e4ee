"""The conformal failure alarm of ``energy-margin monitor``: the margin against the distance baseline.

For each scene, three sets are made from three seeds and analysed (``energy-margin analyze``, one
worker): generated roll-outs (``energy-margin generate``) of the built-in pushing task and of two
example robots, and the built-in pushing task under the control disturbances (``energy-margin
control``: MPPI on the task's cost, on a plant whose friction, pushes and observation noise it does
not know, at the ``hard`` level):

* the *selection* set picks, for each alarm (margin, distance) and alpha, the watched score
  (``success``, ``capture``, ``min``), first monitored frame (0 .. K / 2) and persistence (the
  alarm at the 1st, 2nd or 3rd monitored frame below the threshold): the one whose alarm,
  calibrated on the set's own successes, fires at or before the failure frame on most of its failed
  trajectories (ties: the longer lead time, then the earlier frame, then the smaller persistence);
  ``--persistence 1`` keeps the first frame below, as before;
* the *calibration* set's successful trajectories calibrate the chosen alarm (split-conformal);
* the *test* set measures detection, lead time and the realised false-alarm rate, with 95 %
  bootstrap intervals over its trajectories.

Neither the calibration nor the test set is seen by the selection. Writes the seeds, the budget,
the selection table and the test results.

    python benchmarks/monitor.py --out docs/figures/monitor.json
    python benchmarks/monitor.py --continuation 16 --out docs/figures/monitor_continuation.json
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.scores_file import load_scores
from energy_margin.data.validation import require_valid
from energy_margin.errors import InvalidParameterError
from energy_margin.evaluation.monitor import calibrate_monitor, failure_frames, monitored_grid
from energy_margin.evaluation.monitor_report import evaluate_monitor
from energy_margin.evaluation.monitor_select import select_alarm
from energy_margin.runs.versions import engine_versions

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: Built-in tasks: name -> the ``generate`` command that makes a set's roll-outs.
TASKS = {"pushing": ["generate", "--task", "pushing", "--objects", "10"]}
#: Built-in tasks under the control disturbances: name -> the ``control`` command whose episodes
#: (MPPI on the task's cost, on a plant with other friction, pushes and observation noise) make a set.
CONTROLLED = {
    "pushing_control_hard": ["control", "--task", "pushing", "--policy", "task", "--disturbance", "hard",
                             "--expansions", "0", "--no-progress"],
}  # fmt: skip
#: Scene examples whose model ``write_model.py`` writes.
SCENE_EXAMPLES = ("planar_manipulator", "fetch")
ALPHAS = (0.05, 0.1)
#: Each set-making command's option for the number of roll-outs.
COUNT_OPTION = {"generate": "--trajectories", "control": "--episodes"}


def _scene_command(name: str, folder: Path) -> list[str]:
    """The command that makes a set of scene ``name``: a built-in task's ``generate`` or ``control``,
    or ``generate`` of a scene example (its model written to ``folder``)."""
    if name in TASKS or name in CONTROLLED:
        return {**TASKS, **CONTROLLED}[name]
    out = folder / name
    subprocess.run(
        [sys.executable, str(EXAMPLES / name / "write_model.py"), "--out", str(out)], check=True, capture_output=True
    )
    shutil.copy(EXAMPLES / name / f"{name}.toml", out / f"{name}.toml")
    return ["generate", "--scene", str(out / f"{name}.toml")]


def set_command(command: list[str], *, trajectories: int, frames: int, seed: int, out: Path) -> list[str]:
    """``command`` completed to make one set of ``trajectories`` roll-outs of ``frames`` frames in ``out``."""
    count = COUNT_OPTION[command[0]]
    return [*command, count, str(trajectories), "--frames", str(frames), "--seed", str(seed), "--out", str(out),
            "--overwrite"]  # fmt: skip


def _energy_margin(*arguments: str) -> None:
    """Run one ``energy-margin`` command in its own process."""
    subprocess.run([sys.executable, "-m", "energy_margin", *arguments], check=True)


def _make_set(folder: Path, name: str, scene: list[str], seed: int, args: argparse.Namespace) -> Path:
    """Generate and analyse one set (a set already generated in ``folder`` is kept; ``analyze`` resumes)."""
    path = folder / name
    if not (path / "dataset.json").is_file():
        _energy_margin(*set_command(scene, trajectories=args.trajectories, frames=args.frames, seed=seed, out=path))
    if not (path / "scores.csv").is_file():
        analyse = ["analyze", str(path), "--expansions", str(args.expansions), "--workers", "1", "--no-progress"]
        options = ["--continuation", str(args.continuation), "--capture-gate", args.capture_gate]
        _energy_margin(*analyse, "--seed", str(args.analysis_seed), *options)
    return path


def _scene(name: str, scene: list[str], folder: Path, args: argparse.Namespace) -> dict[str, Any]:
    seeds = {"selection": args.selection_seed, "calibration": args.calibration_seed, "test": args.test_seed}
    paths = {role: _make_set(folder, f"{name}-{role}", scene, seed, args) for role, seed in seeds.items()}
    rows: dict[str, Any] = {}
    for alpha in ALPHAS:
        per_scorer: dict[str, Any] = {}
        for scorer in ("margin", "distance"):
            try:
                best = select_alarm(paths["selection"], alpha=alpha, scorer=scorer, max_persistence=args.persistence)
            except InvalidParameterError as error:
                per_scorer[scorer] = {"refused": f"selection set: {error}"}
                continue
            table = best.candidates
            try:
                found = calibrate_monitor(
                    paths["calibration"],
                    alpha=alpha,
                    scorer=scorer,
                    score=best.score,
                    start_frame=best.start_frame,
                    persistence=best.persistence,
                )
            except InvalidParameterError as error:
                per_scorer[scorer] = {"refused": str(error), "selection": table}
                continue
            result = evaluate_monitor(found, paths["test"], resamples=args.resamples, seed=args.seed)
            per_scorer[scorer] = {
                **result.to_dict(),
                "n_calibration_successes": found.n_successes,
                "selection": table,
            }
            print(
                f"{name} alpha {alpha:.2f} {scorer:8s} score {best.score:7s} from frame {best.start_frame}, "
                f"persistence {best.persistence}: "
                f"detection {result.detection_rate} early {result.early_detection_rate} lead "
                f"{result.lead_time_s} s, false alarms {result.false_alarm_rate} (n = {found.n_successes})",
                flush=True,
            )
        rows[f"alpha_{alpha:g}"] = per_scorer
    # The trees' wall time, summed over every analysed frame of the three sets (kept in scores.csv,
    # so it counts sets analysed by an earlier run in --work too).
    analysis_s = sum(float(load_scores(path)["runtime_s"].sum()) for path in paths.values())
    frames = sum(int(load_scores(path)["frame"].size) for path in paths.values())
    return {
        "seeds": seeds,
        "analysis_s": analysis_s,
        "analysed_frames": frames,
        "test_profile": _profile(paths["test"]),
        **rows,
    }


def _profile(path: Path) -> dict[str, Any]:
    """When the test set's failures become certain, and the margin's mean scores per frame, by outcome."""
    dataset = require_valid(path, overlaps=True, scores=True)
    success = dataset.success_labels()
    failures = failure_frames(dataset.arrays["captured"], success)
    profile: dict[str, Any] = {
        "failure_frame_counts": np.bincount(failures[failures >= 0], minlength=dataset.n_frames).tolist(),
        "frame_time_s": np.asarray(dataset.arrays["frame_time"], dtype=float).mean(axis=0).round(3).tolist(),
    }
    for score in ("success", "capture"):
        grid = monitored_grid(dataset, path, score=score)
        profile[f"mean_{score}_score"] = {
            "successes": grid[success].mean(axis=0).round(3).tolist(),
            "failures": grid[~success].mean(axis=0).round(3).tolist(),
        }
    return profile


def _cpu_s() -> float:
    """CPU seconds of this process and its finished children."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trajectories", type=int, default=70)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--expansions", type=int, default=100)
    parser.add_argument("--selection-seed", type=int, default=2)
    parser.add_argument("--calibration-seed", type=int, default=0)
    parser.add_argument("--test-seed", type=int, default=1)
    parser.add_argument("--analysis-seed", type=int, default=0)
    parser.add_argument(
        "--continuation", type=int, default=0, help="analyze's success continuation (K draws; 0: the tree's own score)"
    )
    parser.add_argument(
        "--capture-gate",
        choices=("current", "none"),
        default="none",
        help="analyze's capture gate (default none, the paper's capture score, with which monitor.json was measured)",
    )
    parser.add_argument(
        "--persistence", type=int, default=3, help="the largest persistence the selection tries (1: first frame below)"
    )
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0, help="seeds the bootstrap resamples")
    scenes = [*TASKS, *CONTROLLED, *SCENE_EXAMPLES]
    parser.add_argument("--scenes", nargs="+", choices=scenes, default=scenes)
    parser.add_argument("--out", type=Path, help="results JSON (scenes of an earlier run not rerun are kept)")
    parser.add_argument("--work", type=Path, help="keep the sets here; analysed sets found there are reused")
    args = parser.parse_args()
    results: dict[str, Any] = {"scenes": {}}
    if args.out is not None and args.out.is_file():
        results = json.loads(args.out.read_text())
    budget = {
        "trajectories_per_set": args.trajectories,
        "frames": args.frames,
        "expansions_per_frame": args.expansions,
        "workers": 1,
        "sets_per_scene": 3,
        "resamples": args.resamples,
        "resample_seed": args.seed,
        "analysis_seed": args.analysis_seed,
        "continuation": args.continuation,
        "capture_gate": args.capture_gate,
        "largest_persistence_tried": args.persistence,
    }
    results["cores"] = os.cpu_count()
    results["versions"] = engine_versions("mujoco")
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(args.work) if args.work is not None else Path(temporary)
        for name in args.scenes:
            started, cpu = time.perf_counter(), _cpu_s()
            results["scenes"][name] = _scene(name, _scene_command(name, folder), folder, args)
            # cpu_s: this run's (sets reused from --work were analysed by an earlier one).
            results["scenes"][name] |= {
                "budget": budget,
                "wall_s": time.perf_counter() - started,
                "cpu_s": _cpu_s() - cpu,
            }
            if args.out is not None:
                args.out.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
            print(
                f"{name}: wall {results['scenes'][name]['wall_s']:.0f} s, cpu {results['scenes'][name]['cpu_s']:.0f} s"
            )


if __name__ == "__main__":
    main()
