"""The home page's single task, step by step: generate, analyze and evaluate pushing with 10 objects.

Runs the three commands of docs/index.md ("A single task, step by step") as a user types them, in a
temporary folder and in this process (``engine_versions.run_cli``), and writes what they measured:
the commands, ``evaluate --json``'s output, the analysis's wall time, the versions and the machine.
The same set is analysed again with the tree's own success score (``--continuation 0``, what
``reproduce``, ``budget`` and ``study`` score) and evaluated, under ``tree_success``. ``--seed S``
runs the same commands with generation and analysis seed S (docs/results/results.md's other sets);
``--cost NAME`` adds ``--cost NAME`` to both analyses (its cost-model table).

    python benchmarks/single_task.py --out docs/figures/pushing_10.json
    python benchmarks/single_task.py --seed 1 --out docs/figures/pushing_10_seed1.json
    python benchmarks/single_task.py --cost energy --out docs/figures/pushing_10_energy.json
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import shutil
import tempfile
import time
from pathlib import Path

from bench_analysis import machine
from energy_margin.runs.versions import engine_versions
from engine_versions import run_cli

__all__: list[str] = []

COMMANDS = (
    "energy-margin generate --task pushing --objects 10 --trajectories 20 --frames 10 --seed 0 --out runs/push10",
    "energy-margin analyze runs/push10 --expansions 300 --workers 2 --seed 0",
    "energy-margin evaluate runs/push10 --json",
)
TREE_SUCCESS = (
    "energy-margin analyze runs/push10-tree --expansions 300 --workers 2 --seed 0 --continuation 0",
    "energy-margin evaluate runs/push10-tree --json",
)


def seeded(commands: tuple[str, ...], seed: int, cost: str | None = None) -> list[str]:
    """The commands with generation and analysis seed ``seed`` (the page's are seed 0).

    With ``cost``, every ``analyze`` command also gets ``--cost COST`` (the default is ``wrench``).
    """
    with_seed = [command.replace("--seed 0", f"--seed {seed}") for command in commands]
    if cost is None:
        return with_seed
    return [f"{command} --cost {cost}" if command.split()[1] == "analyze" else command for command in with_seed]


def _run(command: str) -> str:
    """One command of the page as typed, run in this process (in the current folder); its standard output."""
    return run_cli(command.split()[1:])


def _dataset_only(folder: str, names: list[str]) -> set[str]:
    """What a copy of an analysed dataset leaves out: the analysis's files."""
    return {name for name in names if name.startswith(("scores", "analysis"))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    parser.add_argument("--seed", type=int, default=0, help="generation and analysis seed (default 0, the page's)")
    parser.add_argument("--cost", help="the analyses' cost model (default: analyze's own, wrench)")
    args = parser.parse_args()
    out = args.out.resolve()
    commands, tree_commands = seeded(COMMANDS, args.seed, args.cost), seeded(TREE_SUCCESS, args.seed, args.cost)
    with tempfile.TemporaryDirectory() as work, contextlib.chdir(work):
        _run(commands[0])
        started = time.perf_counter()
        _run(commands[1])
        analyze_s = time.perf_counter() - started
        evaluated = json.loads(_run(commands[2]))
        shutil.copytree("runs/push10", "runs/push10-tree", ignore=_dataset_only)
        _run(tree_commands[0])
        tree_success = json.loads(_run(tree_commands[1]))
    results = {
        "commands": commands,
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
        "versions": engine_versions("mujoco"),
        "analyze_wall_s": round(analyze_s),
        "evaluate": evaluated,
        "tree_success_commands": ["cp -r runs/push10 runs/push10-tree (the dataset's files)", *tree_commands],
        "tree_success": tree_success,
    }
    out.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {out}: analyze {analyze_s:.0f} s")


if __name__ == "__main__":
    main()
