"""Table I on the authors' own frames: true states, their perturbation protocol, their own scores.

On their 10-object pushing frames and their 5-box scooping frames (``../shared/reference``), as
docs/results/robustness.md states the commands: import the frames without their scores, analyse
them (MuJoCo, 300 expansions, the tree's own success, analysis seed 0; the pushing true states
also with seeds 1 and 2), draw five paper-protocol copies (perturbation seed 0), analyse each
with the same seed, and evaluate with their Table I protocol (``--weights uniform
--success-frames 10``). Pushing is analysed twice, with this project's nominal push and with the
pusher coasting as in their planner (``--drive coast``);
scooping's trees are grown once and scored at several λ (``rescore_lambdas``, the scores
``analyze --lambda λ`` gives). Their own scores (``ao_est.csv`` of their original run and of
their perturbed runs 1-5) are evaluated the same way. Every stage resumes from ``--work``.

    python benchmarks/table_one_reference.py --work runs/table-one-reference \\
        --out docs/figures/table_one_reference.json

Without ``../shared`` it prints one ``skip:`` line.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.reference import import_reference
from energy_margin.evaluation.lambda_rescoring import lambda_directory, rescore_lambdas
from energy_margin.evaluation.metrics import evaluate
from energy_margin.robustness.compare import compare_perturbed
from energy_margin.robustness.perturb import perturb_dataset
from energy_margin.runs.versions import engine_versions
from engine_versions import REFERENCE_DATA
from results_document import document_head, work_arguments, write_document

__all__ = ["PROTOCOL", "protocol_row"]

REPEATS = 5
EXPANSIONS = 300
#: Their Table I protocol: every frame of a trajectory weighs the same in its success score.
PROTOCOL = {"weights": "uniform", "success_frames": 10}
#: Scooping's λ [1/J]: the task's own, and down to theirs converted (600) and below.
SCOOPING_LAMBDAS = (10_000.0, 3_000.0, 1_000.0, 600.0, 100.0)
#: Analysis seeds of the pushing true states beside seed 0.
OTHER_SEEDS = (1, 2)
FOLDERS = {"pushing": "planepush-10objects", "scooping": "gripper-5objects"}


def _spread(values: list[float]) -> dict[str, Any]:
    """Mean and population standard deviation (as the paper's ±) of per-copy values, and the values."""
    array = np.asarray(values, dtype=float)
    return {"mean": float(array.mean()), "std": float(array.std()), "values": [float(v) for v in array]}


def protocol_row(path: Path) -> dict[str, Any]:
    """AP at k̂ = 0 and 2 under their protocol (and from the first half), positive rates, time per frame.

    Also the physics time per frame (a later field: files written before it lack the key).
    """
    result = evaluate(path, resamples=0, **PROTOCOL)
    return {
        "capture_ap": result.capture_ap,
        "capture_ap_window2": result.capture_ap_window2,
        "success_ap": result.success_ap,
        "success_ap_first_half": result.success_ap_first_half,
        "capture_positive_rate": result.capture_positive_rate,
        "success_positive_rate": result.success_positive_rate,
        "runtime_per_frame_s": result.runtime_per_frame_s,
        "runtime_per_frame_std_s": result.runtime_per_frame_std_s,
        "physics_per_frame_s": result.physics_per_frame_s,
    }


def _copies_row(true: Path, copies: list[Path]) -> dict[str, Any]:
    """The copies' AP (mean ± std over copies, k̂ = 0 and 2) and score errors, against the true frames' labels."""
    compared = compare_perturbed(true, list(copies), resamples=0, **PROTOCOL).to_dict()
    window2 = [evaluate(copy, resamples=0, **PROTOCOL).capture_ap_window2 for copy in copies]
    return {
        "capture_ap": compared["capture_ap_perturbed"],
        "capture_ap_window2": _spread(window2),
        "success_ap": compared["success_ap_perturbed"],
        "capture_score_error": compared["capture_score_error"],
        "success_score_error": compared["success_score_error"],
    }


def _imported(folder: Path, out: Path, *, drive: str = "nominal", scores: str | None = None) -> Path:
    """The authors' frames as a dataset (resumed when already there)."""
    if not (out / "frames.npz").exists():
        import_reference(folder, out, scores=scores, with_scores=scores is not None, drive=drive, overwrite=True)
    return out


def _paper_copies(path: Path, workers: int) -> list[Path]:
    """Five paper-protocol copies of ``path`` (perturbation seed 0), as ``perturb --protocol paper``."""
    out = path.with_name(path.name + "_paper")
    if all((out / str(r) / "frames.npz").exists() for r in range(1, REPEATS + 1)):
        return [out / str(r) for r in range(1, REPEATS + 1)]
    return perturb_dataset(path, repeats=REPEATS, seed=0, out=out, protocol="paper", workers=workers, overwrite=True)


def _analysed(path: Path, workers: int, seed: int = 0) -> Path:
    """``analyze PATH --expansions 300 --seed S --continuation 0`` (resumes a finished or partial run)."""
    analyze(
        path,
        AnalyzerConfig(expansions=EXPANSIONS, continuation=0, capture_gate="none"),
        seed=seed,
        workers=workers,
        progress=False,
    )
    return path


def _theirs(folder: Path, work: Path) -> dict[str, Any]:
    """Their own scores: the original run on true states, and their perturbed runs 1-5."""
    original = "original" if (folder / "original").is_dir() else "original-data"
    true = protocol_row(_imported(folder, work / f"theirs-{original}", scores=original))
    runs = [protocol_row(_imported(folder, work / f"theirs-{r}", scores=str(r))) for r in range(1, REPEATS + 1)]
    perturbed = {key: _spread([run[key] for run in runs]) for key in ("capture_ap", "success_ap")}
    return {"true": true, "paper": perturbed}


def pushing(work: Path, workers: int) -> dict[str, Any]:
    """Their pushing frames: this analyzer with the nominal push and coasting, and their scores."""
    folder = REFERENCE_DATA / FOLDERS["pushing"]
    rows: dict[str, Any] = {}
    for drive in ("nominal", "coast"):
        true = _analysed(_imported(folder, work / f"push10-{drive}", drive=drive), workers)
        copies = [_analysed(copy, workers) for copy in _paper_copies(true, workers)]
        rows[drive] = {"true": protocol_row(true), "paper": _copies_row(true, copies)}
        # How far the tree's own randomness moves the true states' AP: other analysis seeds.
        rows[drive]["true_by_seed"] = {"0": rows[drive]["true"]}
        for seed in OTHER_SEEDS:
            again = _analysed(_imported(folder, work / f"push10-{drive}-seed{seed}", drive=drive), workers, seed)
            rows[drive]["true_by_seed"][str(seed)] = protocol_row(again)
        print(f"pushing, {drive}: done", flush=True)
    rows["theirs"] = _theirs(folder, work / "push10-theirs")
    return rows


def scooping(work: Path, workers: int) -> dict[str, Any]:
    """Their scooping frames: trees grown once per frame, scored at every λ of ``SCOOPING_LAMBDAS``."""
    folder = REFERENCE_DATA / FOLDERS["scooping"]
    config = AnalyzerConfig(expansions=EXPANSIONS, continuation=0, capture_gate="none")
    true = _imported(folder, work / "scoop5")
    copies = _paper_copies(true, workers)
    scored: dict[str, list[Path]] = {}
    for source in (true, *copies):
        root = source.with_name(source.name + "-lambda")
        rescore_lambdas(source, root, SCOOPING_LAMBDAS, config=config, seed=0, workers=workers, progress=False)
        for lam in SCOOPING_LAMBDAS:
            scored.setdefault(f"{lam:g}", []).append(lambda_directory(root, config.method, EXPANSIONS, lam))
        print(f"scooping, {source.name}: scored at every lambda", flush=True)
    rows: dict[str, Any] = {
        "lambdas": {
            key: {"true": protocol_row(dirs[0]), "paper": _copies_row(dirs[0], dirs[1:])}
            for key, dirs in scored.items()
        }
    }
    rows["theirs"] = _theirs(folder, work / "scoop5-theirs")
    return rows


def main() -> None:
    parser = work_arguments(__doc__)
    parser.add_argument("--tasks", nargs="+", choices=tuple(FOLDERS), default=list(FOLDERS))
    args = parser.parse_args()
    if not REFERENCE_DATA.is_dir():
        print(f"skip: the authors' data is not at {REFERENCE_DATA}")
        return
    started = time.perf_counter()
    measure = {"pushing": pushing, "scooping": scooping}
    found = {task: measure[task](args.work, args.workers) for task in args.tasks}
    figures = {
        **document_head("table_one_reference.py"),
        "versions": engine_versions(),
        "expansions": EXPANSIONS,
        "repeats": REPEATS,
        "protocol": PROTOCOL,
        "wall_s": round(time.perf_counter() - started, 1),
        **found,
    }
    write_document(args.out, figures)
    print(json.dumps({task: found[task] for task in found}, indent=1)[:4000])


if __name__ == "__main__":
    main()
