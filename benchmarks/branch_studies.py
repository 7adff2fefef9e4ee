"""Do a controller's sampled commands change an episode's outcome, and does a cost rank them? (control.md)

Every study of :data:`STUDIES` runs :func:`energy_margin.control.branches.branch_study` on 40
episodes (``--episodes``), seed 0, 8 decision times each: the controller's sampled changes and,
with ``ControllerConfig(noise=0.003)``, changes 100 times smaller; scooping also without any
disturbance and with the blades ``design`` chose (``design_scoop5.json``), and the predictions
looked further ahead (``lookahead`` 10 and 20 periods) and from what the controller does not know
(the true state, the plant's friction). The learned scores use the boosted-tree margins of
``control_policies.py``'s run (``--models``: its ``--work`` folder; without them the ``learned``
score is left out).

Each study is written to ``--out`` as soon as it is done; a study already there is not run again.

    python benchmarks/branch_studies.py --models runs/control-policies --out docs/figures/branch_studies.json
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench_analysis import machine
from energy_margin.control.branches import branch_study
from energy_margin.control.disturbances import get_disturbance
from energy_margin.control.mppi import ControllerConfig
from energy_margin.learning.margin_model import load_margin_model
from energy_margin.runs.versions import engine_versions
from energy_margin.tasks import get_task
from results_document import write_document

__all__ = ["STUDIES", "Study", "chosen_blades"]

ROOT = Path(__file__).resolve().parent.parent
TIMES = {"pushing": (0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6), "scooping": (0.3, 0.5, 0.7, 0.9, 1.1, 1.3, 1.5, 1.7)}
MODELS = {"pushing": "push10-boosting.npz", "scooping": "scoop5-boosting.npz"}


@dataclass(frozen=True)
class Study:
    """One branch study: the task, the sampled changes' scale, the disturbance, the scores, the look-ahead."""

    task: str
    scores: tuple[str, ...]
    noise: float = 0.3
    disturbance: str = "hard"
    lookahead: int = 0
    #: Task settings beside the defaults (``chosen_blades`` fills ``"design"``).
    blades: bool = False
    settings: dict[str, Any] = field(default_factory=dict)


STUDIES: dict[str, Study] = {
    "pushing": Study("pushing", ("task", "margin", "learned")),
    "pushing_small": Study("pushing", ("task",), noise=0.003),
    "scooping": Study("scooping", ("task", "margin", "learned", "oracle_state", "oracle_friction")),
    "scooping_small": Study("scooping", ("task",), noise=0.003),
    "scooping_small_undisturbed": Study("scooping", ("task",), noise=0.003, disturbance="none"),
    "scooping_small_blades": Study("scooping", ("task",), noise=0.003, blades=True),
    "scooping_lookahead_10": Study("scooping", ("task", "margin", "learned"), lookahead=10),
    "scooping_lookahead_20": Study(
        "scooping", ("task", "margin", "learned", "oracle_state", "oracle_friction"), lookahead=20
    ),
    "scooping_undisturbed_lookahead_20": Study("scooping", ("task",), disturbance="none", lookahead=20),
}


def chosen_blades(design: dict[str, Any]) -> dict[str, Any]:
    """The task settings of the design ``design``'s search chose (its first verified design)."""
    return dict(design["verified"][0]["task_config"])


def run(study: Study, episodes: int, models: Path | None) -> dict[str, Any]:
    """One study's summary, its settings and wall time."""
    settings = dict(study.settings)
    if study.blades:
        design = json.loads((ROOT / "docs" / "figures" / "design_scoop5.json").read_text(encoding="utf-8"))
        settings.update(chosen_blades(design))
    model_file = None if models is None else models / MODELS[study.task]
    scores = [name for name in study.scores if name != "learned" or (model_file and model_file.exists())]
    model = load_margin_model(model_file, task_name=study.task) if "learned" in scores and model_file else None
    started = time.perf_counter()
    found = branch_study(
        get_task(study.task, settings), n_objects=5, episodes=episodes,
        disturbance=get_disturbance(study.disturbance), seed=0, decision_times=TIMES[study.task],
        config=ControllerConfig(noise=study.noise, lookahead=study.lookahead), scores=scores, model=model,
    )  # fmt: skip
    return {
        "task": study.task, "noise": study.noise, "disturbance": study.disturbance, "lookahead": study.lookahead,
        "settings": settings, "scores": scores, "model": None if model is None else MODELS[study.task],
        "wall_s": time.perf_counter() - started, "summary": found.summary(),
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    parser.add_argument("--models", type=Path, default=None, help="control_policies.py's --work (learned margins)")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--studies", nargs="+", choices=list(STUDIES), default=list(STUDIES))
    args = parser.parse_args()
    kept = json.loads(args.out.read_text(encoding="utf-8")) if args.out.exists() else {}
    document: dict[str, Any] = {
        "command": "python benchmarks/branch_studies.py --models WORK --out FILE",
        "machine": machine(), "versions": engine_versions(), "episodes": args.episodes,
        "studies": kept.get("studies", {}),
    }  # fmt: skip
    for name in args.studies:
        if name in document["studies"]:
            continue
        document["studies"][name] = run(STUDIES[name], args.episodes, args.models)
        document["load_after"] = os.getloadavg()[0]
        write_document(args.out, document)
        summary = document["studies"][name]["summary"]
        print(f"{name}: {summary['split_states']} of {summary['states']} split, written to {args.out}")


if __name__ == "__main__":
    main()
