"""The seven-robots table of docs/results/generality.md: every example with four ways of setting its perturbation.

For each example, ``bash examples/measure_generality.sh NAME SCENE.toml WORK [record]`` (a 50 × 10
set of generation seed 202 from the scene file as written, the same trajectories with the
perturbation derived from the scene and with the fixed defaults, ``calibrate`` on the file's trees,
then ``benchmarks/bench_generality.py``'s paired verdicts; two workers; everything under ``WORK``
is kept, so a run resumes: a resumed example's ``calibrate_seconds`` is of the resumed run), then
one document of every example's rows:

    python benchmarks/generality_examples.py --work runs/generality --out docs/figures/generality_examples.json

The examples' models are written first (``examples/NAME/write_model.py``).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from energy_margin.runs.versions import engine_versions
from results_document import document_head, work_arguments, write_document

__all__ = ["EXAMPLES", "ORDER", "cell", "table_rows"]

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


#: The order of the ways of setting the perturbation in the table (labels start with these).
ORDER = ("the file's", "fixed defaults", "derived", "calibrated")


def cell(ap: float | None, verdict: dict[str, Any] | None = None) -> str:
    """``0.981 (**ahead** +0.084 [+0.055, +0.123])``; the AP alone without a verdict; ``n/a`` without an AP."""
    if ap is None:
        return "n/a"
    if verdict is None or None in (verdict["difference"], verdict["low"], verdict["high"]):
        return f"{ap:.3f}"
    word = verdict["word"] if verdict["word"] == "level" else f"**{verdict['word']}**"
    return f"{ap:.3f} ({word} {verdict['difference']:+.3f} [{verdict['low']:+.3f}, {verdict['high']:+.3f}])"


def table_rows(name: str, found: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per way of setting the perturbation, then one per baseline: the cells of the table.

    ``found`` is ``bench_generality.py``'s JSON: per settings, each question's AP and verdict.
    """
    ranked = sorted(found["rows"], key=lambda row: [row["settings"].startswith(p) for p in ORDER].index(True))
    rows = []
    for row in ranked:
        cells = [cell(ap, row["verdict"][question]) for question, ap in row["ap"].items()]
        rows.append({"example": "", "settings": row["settings"], **{f"q{i}": c for i, c in enumerate(cells)}})
    for baseline, answers in found["baselines"].items():
        cells = [cell(ap) for ap in answers.values()]
        label = f"baseline: {baseline.replace('_', ' ')}"
        rows.append({"example": "", "settings": label, **{f"q{i}": c for i, c in enumerate(cells)}})
    rows[0]["example"] = f"`{name}`"
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
        command = ["bash", str(ROOT / "examples/measure_generality.sh"), name, str(ROOT / scene), str(args.work)]
        subprocess.run([*command, *(["record"] if recorded else [])], check=True)
        found = json.loads((args.work / name / "row.json").read_text(encoding="utf-8"))
        document["examples"][name] = found
        document["rows"] += table_rows(name, found)
        write_document(args.out, document)
        print(name, "done", flush=True)


if __name__ == "__main__":
    main()
