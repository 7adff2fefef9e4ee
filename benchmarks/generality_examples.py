"""The seven-robots table of docs/results/generality.md: every example with four ways of setting its perturbation.

For each example, ``bash examples/measure_generality.sh NAME SCENE.toml WORK [record]`` (a 50 × 10
set of generation seed 202 from the scene file as written, the same trajectories with the
perturbation derived from the scene and with the fixed defaults, ``calibrate`` on the file's trees,
then ``benchmarks/bench_generality.py``'s paired verdicts; two workers; everything under ``WORK``
is kept, so a run resumes), then one document of every example's rows:

    python benchmarks/generality_examples.py --work runs/generality --out docs/figures/generality_examples.json

The examples' models are written first (``examples/NAME/write_model.py``).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["EXAMPLES", "table_rows"]

ROOT = Path(__file__).resolve().parent.parent
#: Each example: its scene file, and whether its trajectories are recorded roll-outs.
EXAMPLES: dict[str, tuple[str, bool]] = {
    "pushing": ("examples/pushing/pushing.toml", False),
    "jaco": ("examples/jaco/jaco.toml", False),
    "record": ("examples/record/tabletop.toml", True),
    "gym_pusher": ("examples/gym_pusher/gym_pusher.toml", False),
    "fetch": ("examples/fetch/fetch.toml", False),
    "planar_manipulator": ("examples/planar_manipulator/planar_manipulator.toml", False),
    "panda_tray": ("examples/panda_tray/panda_tray.toml", False),
}


def table_rows(name: str, found: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per way of setting the perturbation, then one per baseline, flat for a table block.

    ``found`` is ``bench_generality.py``'s JSON: per settings, each question's AP and verdict.
    """
    rows = []
    for index, row in enumerate(found["rows"]):
        flat: dict[str, Any] = {"example": name if index == 0 else "", "settings": row["settings"]}
        for number, (question, ap) in enumerate(row["ap"].items()):
            verdict = row["verdict"][question]
            flat[f"ap{number}"] = ap
            flat[f"word{number}"] = f"**{verdict['word']}**" if verdict["word"] != "level" else verdict["word"]
            for key in ("difference", "low", "high"):
                flat[f"{key}{number}"] = verdict[key]
        rows.append(flat)
    for baseline, answers in found["baselines"].items():
        flat = {"example": "", "settings": f"baseline: {baseline.replace('_', ' ')}"}
        for number, ap in enumerate(answers.values()):
            flat[f"ap{number}"] = ap
        rows.append(flat)
    return rows


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    document: dict[str, Any] = {
        **document_head("generality_examples.py"),
        "versions": engine_versions(),
        "generation_seed": 202,
        "examples": {},
        "rows": [],
    }
    for name, (scene, recorded) in EXAMPLES.items():
        model = ROOT / Path(scene).parent / "write_model.py"
        if model.exists():
            subprocess.run([sys.executable, str(model)], check=True, stdout=subprocess.DEVNULL)
        started = time.perf_counter()
        command = ["bash", str(ROOT / "examples/measure_generality.sh"), name, str(ROOT / scene), str(args.work)]
        subprocess.run([*command, *(["record"] if recorded else [])], check=True)
        found = json.loads((args.work / name / "row.json").read_text(encoding="utf-8"))
        found["wall_s"] = round(time.perf_counter() - started, 1)
        document["examples"][name] = found
        document["rows"] += table_rows(name, found)
        write_document(args.out, document)
        print(name, "done", flush=True)


if __name__ == "__main__":
    main()
