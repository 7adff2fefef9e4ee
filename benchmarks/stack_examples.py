"""The users' stacks table of docs/howto/integrations.md: each stack's example at today's defaults.

Runs the example of each stack (Meta-World, gymnasium-robotics' Fetch, robosuite, LeRobot's
gym-aloha) with that stack's own interpreter, where the stack and the MuJoCo it needs are
installed (``nox -s "stack(NAME)"`` makes them: ``.nox/stack-NAME/bin/python``; ``--python
NAME=PATH`` names another), on this checkout's code (``PYTHONPATH=src``), writing under
``WORK/EXAMPLE``; an example whose ``results.json`` is already there is not run again. Then one
document: per stack the package and MuJoCo versions, the episodes and how many succeeded, the live
calls (mean ms, mean expansions: they depend on the machine's load, recorded before and after each
run) and ``evaluate``'s verdict on the recorded episodes analysed by ``analyze`` at its defaults.
With ``--keep``, the entries of the stacks not named in ``--stacks`` are kept from the existing
``--out``, each with the date and machine it was measured on (every entry has its own):

    python benchmarks/stack_examples.py --work runs/stacks --out docs/figures/stack_examples.json
"""

from __future__ import annotations

import json
import os
import subprocess
import time
from pathlib import Path
from typing import Any

from generality_examples import cell
from results_document import document_head, work_arguments, write_document

__all__ = ["QUESTIONS", "STACKS", "kept_entries", "questions", "row"]

ROOT = Path(__file__).resolve().parent.parent
#: Each stack: its distribution, its example's script and options.
STACKS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "metaworld": ("metaworld", "examples/metaworld_bin_picking/live_scores.py", ("--episodes", "30")),
    "gymnasium_robotics": ("gymnasium-robotics", "examples/fetch_pick_and_place/live_scores.py", ("--episodes", "50")),
    "robosuite": ("robosuite", "examples/robosuite_pick_place/pick_place.py", ("--episodes", "40")),
    "aloha": ("gym-aloha", "examples/aloha_insertion/insertion.py", ("--episodes", "6")),
}
#: ``evaluate``'s questions in the table's order.
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")


def _load() -> str:
    """The 1-, 5- and 15-minute load averages."""
    return (
        " ".join(Path("/proc/loadavg").read_text(encoding="utf-8").split()[:3])
        if Path("/proc/loadavg").exists()
        else ""
    )


def _interpreters(given: list[str]) -> dict[str, Path]:
    """Each stack's interpreter: ``.nox/stack-NAME/bin/python`` unless ``NAME=PATH`` names another."""
    found = {name: ROOT / ".nox" / f"stack-{name}" / "bin" / "python" for name in STACKS}
    for item in given:
        name, _, path = item.partition("=")
        if name not in STACKS or not path:
            raise SystemExit(f"--python: {item!r} is not NAME=PATH with NAME one of {', '.join(STACKS)}")
        found[name] = Path(path)
    return found


def _run(name: str, python: Path, out: Path) -> dict[str, Any]:
    """Run the stack's example into ``out``; how it ran (``reused`` when its results were there)."""
    _, script, options = STACKS[name]
    command = [str(python), script, *options, "--out", str(out)]
    shown = f"python {script} {' '.join(options)} --out {out.name}"
    if (out / "results.json").is_file():
        return {"command": shown, "reused": True}
    if not python.is_file():
        raise SystemExit(f'{name}: no interpreter at {python} (make it with nox -s "stack({name})" or pass --python)')
    environment = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    before, started = _load(), time.perf_counter()
    subprocess.run(command, check=True, cwd=ROOT, env=environment)
    return {
        "command": shown,
        "reused": False,
        "wall_s": time.perf_counter() - started,
        "load_before": before,
        "load_after": _load(),
    }


def _version(python: Path, distribution: str) -> str | None:
    """The installed version of ``distribution`` in ``python``'s environment (``None`` when unknown)."""
    if not python.is_file():
        return None
    code = f"import importlib.metadata as m; print(m.version({distribution!r}))"
    found = subprocess.run([str(python), "-c", code], capture_output=True, text=True, check=False)
    return found.stdout.strip() or None


def _evaluation(results: dict[str, Any]) -> dict[str, Any]:
    """``evaluate``'s result of the analysed episodes (examples that evaluate the live scores too keep both)."""
    evaluation: dict[str, Any] = results["evaluate"]
    return evaluation.get("analyze", evaluation)


def questions(results: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per question: the margin's AP, the best baseline's name and AP, and the verdict's numbers and word."""
    evaluation = _evaluation(results)
    found = {}
    for question in QUESTIONS:
        verdict = (evaluation.get("verdict") or {}).get(question) or {}
        baseline = verdict.get("baseline")
        found[question] = {
            "margin": evaluation.get(question),
            "baseline": baseline,
            "baseline_ap": evaluation["baselines"][baseline][question] if baseline else None,
            **{key: verdict.get(key) for key in ("difference", "low", "high", "word")},
        }
    return found


def row(name: str, results: dict[str, Any]) -> dict[str, Any]:
    """The table's row of one stack from its example's ``results.json``."""
    episodes = results["episodes"]
    count = episodes if isinstance(episodes, int) else len(episodes)
    cells = {}
    for question, found in questions(results).items():
        verdict = found if found["baseline"] is not None else None
        text = cell(found["margin"], verdict)
        if verdict is not None and found["margin"] is not None:
            text += f" against {found['baseline_ap']:.3f} ({found['baseline'].replace('_', ' ')})"
        cells[question] = text
    timing = results["timing"]
    return {
        "stack": name,
        "mujoco": results["mujoco"],
        "episodes": count,
        "succeeded": round(results["success_rate"] * count),
        "live_mean_ms": timing["mean_ms"],
        "live_mean_expansions": timing["mean_expansions"],
        **cells,
    }


def kept_entries(previous: dict[str, Any], measured: list[str]) -> dict[str, dict[str, Any]]:
    """The entries of ``previous`` (a document) for the stacks not ``measured`` again, with their date and machine."""
    return {
        name: {"date": previous.get("date"), "machine": previous.get("machine"), **entry}
        for name, entry in previous.get("stacks", {}).items()
        if name not in measured
    }


def _in_order(entries: dict[str, dict[str, Any]], document: dict[str, Any]) -> dict[str, Any]:
    """``document`` with ``entries`` as its stacks and rows, in :data:`STACKS`' order."""
    ordered = {name: entries[name] for name in STACKS if name in entries}
    return {**document, "stacks": ordered, "rows": [entry["row"] for entry in ordered.values()]}


def main() -> None:
    parser = work_arguments(__doc__, workers=False, work_help="each example's folder (kept; a finished one is reused)")
    parser.add_argument("--python", nargs="*", default=[], metavar="NAME=PATH", help="a stack's interpreter")
    parser.add_argument("--stacks", nargs="+", choices=tuple(STACKS), default=list(STACKS))
    parser.add_argument(
        "--keep", action="store_true", help="keep the other stacks' entries of an existing --out (each with its date)"
    )
    args = parser.parse_args()
    interpreters = _interpreters(args.python)
    head = document_head("stack_examples.py")
    kept = kept_entries(json.loads(args.out.read_text(encoding="utf-8")), args.stacks) if args.keep else {}
    document: dict[str, Any] = {**head, "stacks": {}, "rows": []}
    for name in args.stacks:
        distribution, script, _ = STACKS[name]
        out = (args.work / Path(script).parent.name).resolve()
        ran = _run(name, interpreters[name], out)
        results = json.loads((out / "results.json").read_text(encoding="utf-8"))
        document["stacks"][name] = {
            **ran,
            "date": head["date"],
            "machine": head["machine"],
            "distribution": distribution,
            "version": _version(interpreters[name], distribution),
            "row": row(name, results),
            "questions": questions(results),
            "evaluate_text": results.get("evaluate_text"),
        }
        document["rows"].append(document["stacks"][name]["row"])
        write_document(args.out, _in_order({**kept, **document["stacks"]}, document))
        print(name, "done", flush=True)


if __name__ == "__main__":
    main()
