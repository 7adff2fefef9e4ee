"""The adaptive budget and the fast contact model on sets that played no part in choosing them.

The table "Checked on sets they were not chosen on" of docs/results/performance.md: four sets of
generation seeds used nowhere else (``generate --seed S``, 10 frames per trajectory) analysed with
the whole budget of 300 expansions and with ``--converge 0.02`` (the 5-object set also with a
second analysis seed and with ``--converge 0.01``; every set also with ``--converge 0.02
--converge-rule projected-reached``), and the authors' 5-object pushing frames
(``import-reference planepush-5objects --no-scores``; the levers were chosen on their 10-object
frames) with the recorded and the fast contacts, analysis seeds 0 and 1. Every analysis is of a
copy of its set, the tree's own success (``--continuation 0``), two workers, then ``evaluate``'s
defaults (capture k̂ = 0 and 2, success from the last 3 frames and from the first half). Every
analysis resumes from ``--work``.

    python benchmarks/unseen_sets.py --work runs/unseen-sets --out docs/figures/unseen_sets.json

Without ``../shared`` the authors' frames are left out.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from converge_ap import QUESTIONS, analysed_copy
from energy_margin.data.generate import generate_dataset
from energy_margin.data.reference import import_reference
from energy_margin.runs.versions import engine_versions
from engine_versions import REFERENCE_DATA
from results_document import document_head, work_arguments, write_document

__all__ = ["ANALYSES", "SETS", "run_key", "with_changes"]

#: The analyses, as ``AnalyzerConfig`` fields beside the budget of 300 expansions.
ANALYSES: dict[str, dict[str, Any]] = {
    "whole budget": {},
    "converge 0.02": {"converge": 0.02},
    "converge 0.01": {"converge": 0.01},
    "reached 0.02": {"converge": 0.02, "converge_rule": "projected-reached"},
    "recorded contacts": {},
    "fast contacts": {"contacts": "fast"},
}
#: Each set: where it comes from and its (analysis, analysis seed) pairs; the first is the reference.
SETS: dict[str, dict[str, Any]] = {
    "pushing5": {
        "label": "pushing n_o = 5 (seed 41, 40)", "task": "pushing", "objects": 5, "seed": 41, "trajectories": 40,
        "runs": [("whole budget", 0), ("whole budget", 1), ("converge 0.02", 0), ("converge 0.02", 1),
                 ("converge 0.01", 0), ("reached 0.02", 0), ("reached 0.02", 1)],
    },
    "pushing10": {
        "label": "pushing n_o = 10 (seed 31, 40)", "task": "pushing", "objects": 10, "seed": 31, "trajectories": 40,
        "runs": [("whole budget", 0), ("converge 0.02", 0), ("reached 0.02", 0)],
    },
    "pushing20": {
        "label": "pushing n_o = 20 (seed 43, 30)", "task": "pushing", "objects": 20, "seed": 43, "trajectories": 30,
        "runs": [("whole budget", 0), ("converge 0.02", 0), ("reached 0.02", 0)],
    },
    "scooping5": {
        "label": "scooping n_o = 5 (seed 34, 30)", "task": "scooping", "objects": 5, "seed": 34, "trajectories": 30,
        "runs": [("whole budget", 0), ("converge 0.02", 0), ("reached 0.02", 0)],
    },
    "their5": {
        "label": "their 5-object frames (20 × 10)", "reference": "planepush-5objects",
        "runs": [("recorded contacts", 0), ("recorded contacts", 1), ("fast contacts", 0), ("fast contacts", 1)],
    },
}  # fmt: skip
FRAMES = 10


def _source(work: Path, name: str, spec: dict[str, Any]) -> Path:
    """The set's frames: generated, or imported from the authors' data, once."""
    out = work / name
    if (out / "frames.npz").exists():
        return out
    if "reference" in spec:
        import_reference(REFERENCE_DATA / spec["reference"], out, with_scores=False, overwrite=True)
    else:
        generate_dataset(
            spec["task"],
            n_objects=spec["objects"],
            n_trajectories=spec["trajectories"],
            n_frames=FRAMES,
            seed=spec["seed"],
            out=out,
            overwrite=True,
        )
    return out


def with_changes(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each row with ``QUESTION_change``: its AP minus that of the set's reference analysis with the same seed.

    The reference is the set's first analysis (the whole budget, or the recorded contacts); a row
    whose seed the reference was not run with is compared with the reference's first seed.
    """
    for row in rows:
        references = [other for other in rows if other["set"] == row["set"] and other["reference"]]
        base = next((other for other in references if other["seed"] == row["seed"]), references[0])
        for key in QUESTIONS:
            row[f"{key}_change"] = None if row[key] is None or base[key] is None else row[key] - base[key]
    return rows


def run_key(row: dict[str, Any]) -> str:
    """A row's key within its set: the analysis (spaces as underscores) and the seed."""
    return f"{row['analysis'].replace(' ', '_')}_seed{row['seed']}"


def main() -> None:
    parser = work_arguments(__doc__)
    args = parser.parse_args()
    started = time.perf_counter()
    rows: list[dict[str, Any]] = []
    for name, spec in SETS.items():
        if "reference" in spec and not REFERENCE_DATA.is_dir():
            print(f"note: the authors' data is not at {REFERENCE_DATA}; {name} is left out")
            continue
        source = _source(args.work, name, spec)
        first = spec["runs"][0][0]
        for analysis, seed in spec["runs"]:
            out = args.work / f"{name}-{analysis.replace(' ', '-')}-seed{seed}"
            found = analysed_copy(source, out, ANALYSES[analysis], seed, args.workers, {})
            rows.append(
                {"set": name, "label": spec["label"], "analysis": analysis, "reference": analysis == first, **found}
            )
            print(name, analysis, seed, {key: found[key] for key in (*QUESTIONS, "mean_expansions")}, flush=True)
    document = {
        **document_head("unseen_sets.py"),
        "versions": engine_versions(),
        "expansions": 300,
        "sets": {name: {key: value for key, value in spec.items() if key != "runs"} for name, spec in SETS.items()},
        "wall_s": round(time.perf_counter() - started, 1),
        "rows": with_changes(rows),
        # The same rows by set and run, for quoting: ``by_set/pushing5/converge_0.02_seed1``.
        "by_set": {name: {run_key(row): row for row in rows if row["set"] == name} for name in SETS},
    }
    write_document(args.out, document)


if __name__ == "__main__":
    main()
