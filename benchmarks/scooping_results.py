"""Scooping's measured results: AP per λ on two generated sets, and the time per frame.

Two sets of the scooping task at its defaults (5 boxes, 20 trajectories × 10 frames, generation
seeds 0 and 1; seed 0 is the set of ``reproduce``'s Table I). Every frame's tree is grown once
(300 expansions, the tree's own success, ``--continuation 0``, analysis seed 0, two workers) and
scored at every λ of ``LAMBDAS`` (``analyze --lambda λ`` gives the same scores; the task's own is
10 000 J⁻¹), then evaluated (capture k̂ = 0 and 2, success from the last 3 frames and from the
first half, with the current-state and chance baselines). The time per frame is measured on a
third set (generation seed 2, 3 trajectories × 10 frames) analysed by one process.

    python benchmarks/scooping_results.py --work runs/scooping-results --out docs/figures/scooping_results.json

Every stage resumes from ``--work``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.lambda_rescoring import lambda_directory, rescore_lambdas
from energy_margin.evaluation.metrics import evaluate
from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["evaluation_row"]

EXPANSIONS = 300
#: Inverse temperatures [1/J] every tree is scored at: 0 (the fraction of nodes), the authors' 3, ... the task's 10 000.
LAMBDAS = (0.0, 3.0, 100.0, 1_000.0, 3_000.0, 10_000.0, 30_000.0, 100_000.0)
SETS = {"seed0": 0, "seed1": 1}
SIZE = {"n_objects": 5, "n_trajectories": 20, "n_frames": 10}
TIMING = {"seed": 2, "n_objects": 5, "n_trajectories": 3, "n_frames": 10}
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")


def _generated(out: Path, seed: int, size: dict[str, int]) -> Path:
    """``generate --task scooping ... --seed S --out OUT`` (kept when already there)."""
    if not (out / "frames.npz").exists():
        generate_dataset("scooping", out=out, seed=seed, overwrite=True, **size)
    return out


def evaluation_row(path: Path) -> dict[str, Any]:
    """``evaluate PATH``'s AP per question, its baselines', the positive rates and the time per frame."""
    result = evaluate(path, resamples=0)
    return {
        **{question: getattr(result, question) for question in QUESTIONS},
        "baselines": {
            name: {question: values.get(question) for question in QUESTIONS}
            for name, values in result.baselines.items()
        },
        "capture_positive_rate": result.capture_positive_rate,
        "capture_positive_rate_window2": result.capture_positive_rate_window2,
        "success_positive_rate": result.success_positive_rate,
        "n_trajectories": result.n_trajectories,
        "runtime_per_frame_s": result.runtime_per_frame_s,
        "runtime_per_frame_std_s": result.runtime_per_frame_std_s,
        "physics_per_frame_s": result.physics_per_frame_s,
    }


def lambda_rows(work: Path, workers: int) -> dict[str, Any]:
    """Per set: every λ's evaluation (rows in ``LAMBDAS`` order)."""
    config = AnalyzerConfig(expansions=EXPANSIONS, continuation=0, capture_gate="none")
    found: dict[str, Any] = {}
    for name, seed in SETS.items():
        dataset = _generated(work / f"scoop5-{name}", seed, SIZE)
        root = work / f"scoop5-{name}-lambda"
        rescore_lambdas(dataset, root, LAMBDAS, config=config, seed=0, workers=workers, progress=False)
        found[name] = [
            {"lambda": lam, **evaluation_row(lambda_directory(root, config.method, EXPANSIONS, lam))} for lam in LAMBDAS
        ]
        print(f"{name}: scored at every lambda", flush=True)
    return found


def timing(work: Path) -> dict[str, Any]:
    """Time per frame of one process (``analyze TIMING --workers 1 --continuation 0``)."""
    size = {key: value for key, value in TIMING.items() if key != "seed"}
    dataset = _generated(work / "scoop5-timing", TIMING["seed"], size)
    analyze(
        dataset,
        AnalyzerConfig(expansions=EXPANSIONS, continuation=0, capture_gate="none"),
        seed=0,
        workers=1,
        progress=False,
    )
    return evaluation_row(dataset)


def main() -> None:
    parser = work_arguments(__doc__)
    args = parser.parse_args()
    started = time.perf_counter()
    rows = lambda_rows(args.work, args.workers)
    one_process = timing(args.work)
    figures = {
        **document_head("scooping_results.py"),
        "versions": engine_versions(),
        "expansions": EXPANSIONS,
        "workers": args.workers,
        "lambdas": list(LAMBDAS),
        "sets": rows,
        "timing": {**TIMING, **one_process},
        "wall_s": round(time.perf_counter() - started, 1),
    }
    write_document(args.out, figures)
    for name, entries in rows.items():
        for entry in entries:
            aps = " ".join(f"{entry[q]:.3f}" if entry[q] is not None else "-" for q in QUESTIONS)
            print(f"{name} lambda {entry['lambda']:>8g}: {aps}")
    per_frame, physics = one_process["runtime_per_frame_s"], one_process["physics_per_frame_s"]
    print(f"timing: {per_frame:.3f} s per frame, physics {physics:.3f}")


if __name__ == "__main__":
    main()
