"""The capture gate on every example and both built-in tasks: capture AP with and without it.

The table "The capture gate" of docs/results/generality.md. Each scene gets a 20 × 10 set of
generation seed ``--seed`` (502 for the page; the gate was looked at first on seed 501), made as a
user makes one (``energy-margin generate --scene``, or for ``record`` the recorded roll-outs of
``examples/record/simulate.py`` through ``energy-margin record``), analysed once at ``analyze``'s
defaults but ``--capture-gate none`` (two workers, analysis seed 0). The gated capture score is
that score times the frame's own capture label (the label at k̂ = 0), which is what
``--capture-gate current`` writes (``tests/analysis/test_capture_gate.py`` checks it on a tree
analysed both ways), so one tree per frame gives both columns. ``evaluate``'s capture questions at
k̂ = 0, 2 and 4 and early success from the first 3 and the first 5 frames (k̄ = 3; the same both
ways, the gate does not touch the success score), each with the paired verdict against the best
baseline (1000 resamples, seed 0).

    python benchmarks/capture_gate.py --work runs/capture-gate --out docs/figures/capture_gate.json [--seed 502]

The examples' models are written first (``examples/NAME/write_model.py``); everything under
``--work`` is kept, so a run resumes.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import Questions
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.verdict import verdicts
from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["SCENES", "gated_rows"]

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
#: The scenes: an example's scene file, the recorded example, or a built-in task with its objects.
SCENES: dict[str, dict[str, Any]] = {
    "jaco": {"scene": "jaco"},
    "gym_pusher": {"scene": "gym_pusher"},
    "planar_manipulator": {"scene": "planar_manipulator"},
    "pushing (example)": {"scene": "pushing"},
    "fetch": {"scene": "fetch"},
    "panda_tray": {"scene": "panda_tray"},
    "record": {"record": "record/tabletop.toml"},
    "pushing (built-in, n_o = 10)": {"task": "pushing", "objects": 10},
    "scooping (built-in, n_o = 5)": {"task": "scooping", "objects": 5},
}
TRAJECTORIES, FRAMES = 20, 10
WINDOWS = (0, 2, 4)
RESAMPLES = 1000


def _cli(*arguments: str) -> None:
    subprocess.run([sys.executable, "-m", "energy_margin", *arguments], check=True, stdout=subprocess.DEVNULL)


def _dataset(work: Path, name: str, spec: dict[str, Any], seed: int) -> Path:
    """The scene's set, made once."""
    out = work / name.split(" ")[0] if "task" not in spec else work / f"{spec['task']}-builtin"
    if (out / "frames.npz").exists():
        return out
    sets = ("--trajectories", str(TRAJECTORIES), "--frames", str(FRAMES), "--seed", str(seed))
    if "scene" in spec:
        example = EXAMPLES / spec["scene"]
        if (example / "write_model.py").exists():
            subprocess.run([sys.executable, str(example / "write_model.py")], check=True, stdout=subprocess.DEVNULL)
        _cli("generate", "--scene", str(example / f"{spec['scene']}.toml"), *sets, "--out", str(out), "--overwrite")
    elif "record" in spec:
        logs = work / "record-logs"
        if not logs.is_dir():
            simulate = EXAMPLES / "record" / "simulate.py"
            subprocess.run(
                [
                    sys.executable,
                    str(simulate),
                    "--rollouts",
                    str(TRAJECTORIES),
                    "--seed",
                    str(seed),
                    "--out",
                    str(logs),
                ],
                check=True,
                stdout=subprocess.DEVNULL,
            )
        runs = sorted(str(path) for path in logs.glob("run_*.npz"))
        _cli("record", "--scene", str(EXAMPLES / spec["record"]), *runs, "--frames", str(FRAMES), "--out", str(out))
    else:
        generate_dataset(
            spec["task"],
            n_objects=spec["objects"],
            n_trajectories=TRAJECTORIES,
            n_frames=FRAMES,
            seed=seed,
            out=out,
            overwrite=True,
        )
    return out


def questions_of(dataset: Any) -> Questions:
    """Capture at k̂ = 0, 2, 4 and early success from the first 3 and 5 frames (k̄ = 3, linear weights)."""
    return Questions(
        dataset,
        3,
        capture_windows={f"capture_k{window}": window for window in WINDOWS},
        success_spans={"success_first3": (0, 3), "success_first5": (0, 5)},
    )


def gated_rows(path: Path) -> dict[str, Any]:
    """AP and verdict of each question without and with the gate (early success: the same both ways)."""
    dataset = load_dataset(path)
    scores = load_scores(path)
    capture = score_grid(dataset, scores, "capture_score")
    success = score_grid(dataset, scores, "success_score")
    gated = capture * dataset.arrays["captured"]
    grids = baseline_grids(dataset)
    questions = questions_of(dataset)
    every = np.arange(dataset.n_trajectories)
    options = {"capture_window": 0, "success_frames": 3, "weights": "linear", "resamples": RESAMPLES, "seed": 0}
    found: dict[str, Any] = {"uncaptured_share": float(1.0 - dataset.arrays["captured"].mean())}
    baselines = {name: questions.answer(*grid, every) for name, grid in grids.items()}
    both = {}
    for name, grid in (("none", capture), ("current", gated)):
        answers = questions.answer(grid, success, every)
        verdict = verdicts(dataset, (grid, success), grids, questions=questions, **options)
        both[name] = {
            question: {"ap": answers[question], "verdict": verdict[question].to_dict()} for question in answers
        }
    for question in questions.names:
        found[question] = {
            "baselines": {name: answers[question] for name, answers in baselines.items()},
            "none": both["none"][question],
            "current": both["current"][question],
        }
    found["changed_frames"] = int(np.count_nonzero(gated != capture))
    return found


def main() -> None:
    parser = work_arguments(__doc__)
    parser.add_argument("--seed", type=int, default=502, help="generation seed of every set")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    document: dict[str, Any] = {
        **document_head("capture_gate.py"),
        "versions": engine_versions(),
        "generation_seed": args.seed,
        "analysis_seed": 0,
        "trajectories": TRAJECTORIES,
        "frames": FRAMES,
        "resamples": RESAMPLES,
        "scenes": {},
        "rows": [],
    }
    for name, spec in SCENES.items():
        path = _dataset(args.work, name, spec, args.seed)
        options = ("--capture-gate", "none", "--workers", str(args.workers), "--seed", "0", "--no-progress")
        _cli("analyze", str(path), *options)
        found = gated_rows(path)
        document["scenes"][name] = found
        labels = {f"capture_k{window}": f"capture k̂ = {window}" for window in WINDOWS}
        labels.update({"success_first3": "early success (first 3 frames)", "success_first5": "early success (first 5)"})
        questions = [(label, found[key]) for key, label in labels.items()]
        for question, entry in questions:
            document["rows"].append(
                {
                    "scene": name,
                    "question": question,
                    "none": entry["none"]["ap"],
                    "none_word": entry["none"]["verdict"]["word"],
                    "none_difference": entry["none"]["verdict"]["difference"],
                    "current": entry["current"]["ap"],
                    "current_word": entry["current"]["verdict"]["word"],
                    "current_difference": entry["current"]["verdict"]["difference"],
                    "current_low": entry["current"]["verdict"]["low"],
                    "current_high": entry["current"]["verdict"]["high"],
                }
            )
        print(
            name,
            {
                key: (found[key]["none"]["ap"], found[key]["current"]["ap"])
                for key in found
                if key.startswith("capture")
            },
        )
        write_document(args.out, document)


if __name__ == "__main__":
    main()
