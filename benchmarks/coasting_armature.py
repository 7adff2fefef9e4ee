"""The armature of a robot held still or coasting during analysis, measured on recorded demonstrations.

A recorded roll-out whose commands are not known can be analysed with its robot held still
(``robot = "still"``) or keeping each frame's joint velocities (``"coasting"``): its joints then
carry a heavy armature (``STILL_ARMATURE``, ``COASTING_ARMATURE`` in
``energy_margin.sim.mujoco_model``) so that the objects' contacts, gravity and its actuators move
or slow it little. How heavy changes what the trees find: a body of enormous inertia moving into
the objects throws them, a light one is pushed about by them. This benchmark analyses the same
recorded sets of ``benchmarks/robomimic_demos.py`` (the Jaco example's sweeps written as robomimic
HDF5 with ``examples/robomimic/write_demos.py --seed DEMONSTRATION_SEED``; ``demos_coasting``,
``demos_still``: the drawn speed, ``coasting``, ``still``: the declared one) once per armature (each
analysis in one process whose armature constants are set to the value, ``analyze`` at its
defaults, 300 expansions, seed 0, one worker) and reports, per set and armature, the AP of every
question of ``robomimic_demos.py`` with its verdict against the baselines, and the margin at each
armature minus the margin at the package's armature for that robot (paired 95 % bootstrap
interval over trajectories, 1000 resamples, seed 0). The armatures were chosen on demonstration
seed 1 (the second command); the docs quote seed 0 (the first):

    python benchmarks/coasting_armature.py --sets coasting,demos_coasting --work runs/armature \\
        --out docs/figures/coasting_armature.json
    python benchmarks/coasting_armature.py --demonstration-seed 1 --work runs/armature_seed1 \\
        --out docs/figures/coasting_armature_seed1.json

Everything under ``--work`` is kept: the recorded sets under their names, each armature's
analyses under ``armature-A/`` (a run resumes).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.verdict import verdicts
from energy_margin.runs.versions import engine_versions
from energy_margin.sim.mujoco_model import COASTING_ARMATURE, STILL_ARMATURE
from results_document import document_head, work_arguments, write_document
from robomimic_demos import EXPANSIONS, ROOT, _analysed, _sets, set_questions, set_results

#: The sets this benchmark analyses (``robomimic_demos.py``'s with a held or coasting robot).
SETS = ("demos_coasting", "demos_still", "coasting", "still")
#: The armatures compared, kg m^2 (or kg for a slide).
ARMATURES = (1e8, 1e6)
#: What the analysis copies of a recorded set (its analysis, if any, is not copied; ``source``: where it has one).
RECORDED_FILES = ("dataset.json", "frames.npz", "source")
#: Runs ``energy-margin`` in one process with both armature constants set to ``sys.argv[1]``.
_PATCHED_CLI = (
    "import sys; import energy_margin.sim.mujoco_model as model; "
    "model.STILL_ARMATURE = model.COASTING_ARMATURE = float(sys.argv.pop(1)); "
    "from energy_margin.cli import main; sys.exit(main())"
)


def package_armature(robot: str) -> float:
    """The armature the package gives a robot that is ``"still"`` or ``"coasting"``."""
    return STILL_ARMATURE if robot == "still" else COASTING_ARMATURE


def armature_copy(recorded: Path, directory: Path) -> Path:
    """A copy of the recorded set ``recorded`` at ``directory`` (kept); a scene file of the set's own is copied too."""
    if not (directory / "dataset.json").exists():
        directory.mkdir(parents=True, exist_ok=True)
        for name in RECORDED_FILES:
            source = recorded / name
            if source.is_dir():
                shutil.copytree(source, directory / name, dirs_exist_ok=True)
            elif source.exists():
                shutil.copy2(source, directory / name)
        if (recorded / "source").is_dir():  # record --format robomimic writes the scene there: use the copy's
            document = json.loads((directory / "dataset.json").read_text(encoding="utf-8"))
            scene_file = directory / "source" / Path(document["task_config"]["scene_file"]).name
            document["task_config"]["scene_file"] = str(scene_file)
            (directory / "dataset.json").write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    return directory


def patched_cli(armature: float) -> Callable[..., None]:
    """A runner of ``energy-margin`` commands in a process whose armature constants are ``armature``."""

    def run(*argv: str | Path | int) -> None:
        found = subprocess.run([sys.executable, "-c", _PATCHED_CLI, repr(armature), *map(str, argv)], cwd=ROOT,
                               capture_output=True, text=True)  # fmt: skip
        if found.returncode:
            sys.exit(f"{' '.join(map(str, argv[:2]))} failed: {(found.stderr or found.stdout).strip()[-400:]}")

    return run


def against_package(directory: Path, package: Path) -> dict[str, dict[str, Any]]:
    """The margin of ``directory`` minus the margin of ``package`` (the same set), per question, paired."""
    dataset = load_dataset(directory)
    grids = [
        tuple(score_grid(dataset, load_scores(where), column) for column in ("capture_score", "success_score"))
        for where in (directory, package)
    ]
    questions = set_questions(dataset)
    found = verdicts(dataset, grids[0], {"package": grids[1]}, capture_window=0, success_frames=3, weights="linear",
                     resamples=1000, seed=0, questions=questions)  # fmt: skip
    return {name: found[name].to_dict() for name in questions.names}


def comparison_rows(name: str, entry: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per question and armature other than the package's: both margins and their paired difference."""
    package = entry["armatures"][f"{entry['package_armature']:g}"]
    rows = []
    for armature, found in entry["armatures"].items():
        if found is package:
            continue
        for question, answer in found["questions"].items():
            change = found["against_package"][question]
            rows.append(
                {
                    "set": name,
                    "robot": entry["robot"],
                    "question": question,
                    "package_armature": entry["package_armature"],
                    "package_margin": package["questions"][question]["cell"],
                    "armature": float(armature),
                    "margin": answer["cell"],
                    "difference": change["difference"],
                    "low": change["low"],
                    "high": change["high"],
                    "word": change["word"],
                }
            )
    return rows


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--demonstration-seed", type=int, default=0, help="write_demos.py's --seed")
    parser.add_argument("--sets", default="demos_coasting,demos_still", help=f"the sets, of {', '.join(SETS)}")
    parser.add_argument("--armatures", default=",".join(f"{a:g}" for a in ARMATURES), help="kg m^2, comma-separated")
    args = parser.parse_args()
    names = tuple(name.strip() for name in args.sets.split(","))
    if not names or not set(names) <= set(SETS):
        parser.error(f"--sets: names of {', '.join(SETS)}, got {args.sets!r}")
    try:
        armatures = tuple(float(value) for value in args.armatures.split(","))
    except ValueError:
        parser.error(f"--armatures: numbers separated by commas, got {args.armatures!r}")
    args.work.mkdir(parents=True, exist_ok=True)
    recorded = _sets(args.work, names, args.demonstration_seed)
    document: dict[str, Any] = {
        **document_head("coasting_armature.py"),
        "versions": engine_versions(),
        "demonstration_seed": args.demonstration_seed,
        "expansions": EXPANSIONS,
        "analysis_seed": 0,
        "workers": 1,
        "package_armature": {"still": STILL_ARMATURE, "coasting": COASTING_ARMATURE},
        "sets": {},
        "rows": [],
    }
    for name, source in recorded.items():
        robot = "still" if name.endswith("still") else "coasting"
        package = package_armature(robot)
        where = {a: armature_copy(source, args.work / f"armature-{a:g}" / name) for a in {*armatures, package}}
        entry: dict[str, Any] = {"robot": robot, "package_armature": package, "armatures": {}}
        seconds = {armature: _analysed(directory, patched_cli(armature)) for armature, directory in where.items()}
        for armature, directory in sorted(where.items(), reverse=True):
            found = set_results(directory)
            difference = against_package(directory, where[package])
            entry["armatures"][f"{armature:g}"] = {
                **found,
                "seconds_per_frame": seconds[armature],
                "against_package": difference,
            }
            print(f"{name} {armature:g}: " + "; ".join(f"{q} {a['cell']}" for q, a in found["questions"].items()))
        document["rows"] += comparison_rows(name, entry)
        document["sets"][name] = entry
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
