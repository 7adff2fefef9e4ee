"""Demonstrations in robomimic's layout, converted and analysed at the defaults (docs/howto/integrations.md).

The Jaco example's sweeps (``examples/robomimic/write_demos.py`` with ``--demonstration-seed``, 0
by default; states every 5 physics steps) give seven sets, each recorded with ``energy-margin
record`` (10 frames) and analysed with ``energy-margin analyze`` at its defaults (300 expansions,
seed 0, one worker):

* ``demos``, ``demos_coasting`` and ``demos_still``: 50 demonstrations at the drawn speed
  (0.9-1.1), converted from the HDF5 file (``--format robomimic``,
  ``examples/robomimic/jaco_demos.toml``) at ``record``'s default (the robot following each
  demonstration's recorded joint path in analysis), with ``--robot coasting`` (it keeps each
  frame's joint velocities) and with ``--robot still``;
* ``recorded``, ``coasting``, ``still`` and ``declared``: 50 sweeps at the declared speed,
  converted from the HDF5 file (``--robot recorded``, ``coasting``, ``still``) and recorded from
  the same sweeps written as ``.npz`` roll-outs with the Jaco example's own scene
  (``examples/jaco/jaco.toml``: the analysis follows the declared sweep). Their frames and labels
  are the same; they differ only in what the robot does during a tree's propagation.

For each set: capture AP at k̂ = 0, 2, 4 and success from the first 3 and 5 frames and the last 3
(k̄ = 3), beside the current-state and distance baselines, each with the margin minus the best
baseline, a paired 95 % bootstrap interval over the trajectories (1000 resamples, seed 0) and
its word; the analysis's wall time per frame. Everything under ``--work`` is kept (a run resumes).
``record``'s default (the recorded path) was chosen on the demonstrations of seed 1 (the second
command); the figures the docs quote are those of seed 0 (the first):

    python benchmarks/robomimic_demos.py --work runs/robomimic --out docs/figures/robomimic_demos.json
    python benchmarks/robomimic_demos.py --demonstration-seed 1 --sets demos,demos_coasting,demos_still \
        --work runs/robomimic_seed1 --out docs/figures/robomimic_demos_seed1.json
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench_generality import questions_of
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import JOURNAL_FILE, load_scores
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import Questions
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.verdict import verdicts
from energy_margin.runs.versions import engine_versions
from generality_examples import cell
from results_document import document_head, work_arguments, write_document

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
DEMOS = 50
FRAMES = 10
EXPANSIONS = 300
#: The sets, in the document's order.
SETS = ("demos", "demos_coasting", "demos_still", "recorded", "coasting", "still", "declared")
#: The questions: bench_generality's five, then success from the last 3 frames.
LAST_3 = "success, last 3"


def _run(*argv: str | Path) -> None:
    """Run a command of this checkout's interpreter; stop the benchmark with its message on failure."""
    found = subprocess.run([sys.executable, *map(str, argv)], cwd=ROOT, capture_output=True, text=True)
    if found.returncode:
        sys.exit(f"{' '.join(map(str, argv[:3]))} failed: {(found.stderr or found.stdout).strip()[-400:]}")


def _cli(*argv: str | Path) -> None:
    _run("-m", "energy_margin", *argv)


def _sets(work: Path, names: tuple[str, ...] = SETS, seed: int = 0) -> dict[str, Path]:
    """Write the demonstrations of ``seed`` and record the sets ``names`` (each once: kept under ``work``)."""
    if not (EXAMPLES / "jaco" / "jaco_scene.xml").exists():
        _run(EXAMPLES / "jaco" / "write_model.py")
    drawn, nominal, npz = work / "demos.hdf5", work / "nominal.hdf5", work / "nominal_npz"
    if not drawn.exists():
        _run(EXAMPLES / "robomimic" / "write_demos.py", "--demos", DEMOS, "--seed", seed, "--out", drawn)
    if not nominal.exists() and set(names) & {"coasting", "still", "recorded", "declared"}:
        _run(EXAMPLES / "robomimic" / "write_demos.py", "--demos", DEMOS, "--seed", seed, "--nominal-speed",
             "--npz", npz, "--out", nominal)  # fmt: skip
    demos_scene = EXAMPLES / "robomimic" / "jaco_demos.toml"
    sets = {name: work / name for name in names}
    sources = {
        "demos": ["--format", "robomimic", drawn, "--scene", demos_scene],
        "demos_still": ["--format", "robomimic", drawn, "--scene", demos_scene, "--robot", "still"],
        "demos_coasting": ["--format", "robomimic", drawn, "--scene", demos_scene, "--robot", "coasting"],
        "coasting": ["--format", "robomimic", nominal, "--scene", demos_scene, "--robot", "coasting"],
        "still": ["--format", "robomimic", nominal, "--scene", demos_scene, "--robot", "still"],
        "recorded": ["--format", "robomimic", nominal, "--scene", demos_scene, "--robot", "recorded"],
        "declared": ["--scene", EXAMPLES / "jaco" / "jaco.toml", *sorted(npz.glob("demo_*.npz"))],
    }
    for name, directory in sets.items():
        if not (directory / "dataset.json").exists():
            _cli("record", *sources[name], "--frames", FRAMES, "--out", directory)
    return sets


#: Where a set's analysis time is kept beside its scores (a resumed benchmark reports it again).
SECONDS_FILE = "seconds_per_frame.json"


def _analysed(directory: Path, cli: Callable[..., None] | None = None) -> float | None:
    """Analyse ``directory`` at the defaults; its wall time per frame, s (``None``: analysed by an interrupted run).

    ``cli`` runs the command (``energy-margin`` and its arguments) in another process (``None``: this
    checkout's interpreter).
    """
    kept = directory / SECONDS_FILE
    if kept.exists():
        return float(json.loads(kept.read_text())["seconds_per_frame"])
    if (directory / "scores.csv").exists():
        return None
    resumed = (directory / JOURNAL_FILE).exists()
    started = time.perf_counter()
    (cli or _cli)("analyze", directory, "--expansions", EXPANSIONS, "--workers", 1, "--seed", 0, "--no-progress")
    if resumed:
        return None
    dataset = load_dataset(directory)
    seconds = (time.perf_counter() - started) / (dataset.n_trajectories * dataset.n_frames)
    kept.write_text(json.dumps({"seconds_per_frame": seconds}) + "\n")
    return seconds


def set_questions(dataset: Any) -> Questions:
    """The questions of a set: bench_generality's five, then success from the last 3 frames."""
    early = questions_of(dataset)
    return Questions(
        dataset,
        3,
        capture_windows={name: window for name, window in zip(early.capture, (0, 2, 4), strict=True)},
        success_spans={**{name: (span.start, span.stop) for name, span in early.spans.items()}, LAST_3: (None, None)},
    )


def set_results(directory: Path, *, resamples: int = 1000) -> dict[str, Any]:
    """Each question's AP and verdict for the margin, the baselines' APs, the positive rates."""
    dataset = load_dataset(directory)
    scores = load_scores(directory)
    grids = (score_grid(dataset, scores, "capture_score"), score_grid(dataset, scores, "success_score"))
    questions = set_questions(dataset)
    every = np.arange(dataset.n_trajectories)
    baselines = baseline_grids(dataset)
    found = verdicts(dataset, grids, baselines, capture_window=0, success_frames=3, weights="linear",
                     resamples=resamples, seed=0, questions=questions)  # fmt: skip
    answers = questions.answer(*grids, every)
    return {
        "trajectories": dataset.n_trajectories,
        "frames": dataset.n_frames,
        "captured_share": float(np.mean(dataset.capture_labels(0))),
        "success_share": float(np.mean(dataset.success_labels())),
        "robot": dataset.task.loaded.spec.motion.robot,
        "questions": {
            name: {
                "margin": answers[name],
                "verdict": found[name].to_dict(),
                "cell": cell(answers[name], found[name].to_dict()),
            }
            for name in questions.names
        },
        "baselines": {name: questions.answer(*grid, every) for name, grid in baselines.items()},
    }


def table_rows(sets: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per set and question: the margin's cell, the baselines' APs (``n/a`` where undefined)."""
    rows = []
    for name, found in sets.items():
        for question, answer in found["questions"].items():
            baselines = {
                baseline: "n/a" if answers[question] is None else f"{answers[question]:.3f}"
                for baseline, answers in found["baselines"].items()
            }
            rows.append({"set": name, "question": question, "margin": answer["cell"], **baselines})
    return rows


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--demonstration-seed", type=int, default=0, help="write_demos.py's --seed")
    parser.add_argument("--sets", default=",".join(SETS), help=f"the sets, of {', '.join(SETS)}")
    args = parser.parse_args()
    names = tuple(name.strip() for name in args.sets.split(","))
    if not names or not set(names) <= set(SETS):
        parser.error(f"--sets: names of {', '.join(SETS)}, got {args.sets!r}")
    args.work.mkdir(parents=True, exist_ok=True)
    sets = _sets(args.work, names, args.demonstration_seed)
    document: dict[str, Any] = {
        **document_head("robomimic_demos.py"),
        "versions": engine_versions(),
        "demonstrations": DEMOS,
        "demonstration_seed": args.demonstration_seed,
        "expansions": EXPANSIONS,
        "analysis_seed": 0,
        "workers": 1,
        "sets": {},
    }
    for name, directory in sets.items():
        seconds = _analysed(directory)
        document["sets"][name] = {**set_results(directory), "seconds_per_frame": seconds}
        rows = document["sets"][name]["questions"]
        print(f"{name}: " + "; ".join(f"{question} {row['cell']}" for question, row in rows.items()), flush=True)
    document["rows"] = table_rows(document["sets"])
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
