"""Names per concept: how many spellings one idea has across the command line, Python and files.

Reads a checkout (this one by default, or ``--root`` another, e.g. a worktree of an earlier commit)
and, for each concept below, lists the spellings it finds:

* on the command line: the visible options of every command (a deprecated spelling kept for one
  release is hidden from the help and not counted);
* in Python: parameters of public functions and fields of public classes in ``src`` (for the counts
  of trajectories and frames, only those annotated ``int``); ``progress`` by its annotation (a bool,
  a callback, or the one ``Progress`` type);
* in files: the settings file each run directory writes first (``<command>.json`` or
  ``<command>_settings.json``);
* the learned margin's kind: the command line's default and the Python default of the same choice.

    python benchmarks/names_per_concept.py --out docs/figures/names_after.json
    python benchmarks/names_per_concept.py --root /tmp/before --out docs/figures/names_before.json
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path
from typing import Any

from checkout import checkout_arguments, commit_of, run_on, write_figures

#: Concept -> the command-line spellings and the Python spellings looked for.
CONCEPTS: dict[str, dict[str, tuple[str, ...]]] = {
    "expansions per frame": {
        "cli": (
            "--iterations",
            "--budgets",
            "--score-expansions",
            "--lambda-budget",
            "--expansions",
            "--lambda-expansions",
        ),
        "python": ("iterations", "budgets", "score_expansions", "lambda_budget", "expansions", "lambda_expansions"),
    },
    "trajectories per dataset": {"cli": ("--trajectories",), "python": ("trajectories", "n_trajectories")},
    "frames per trajectory": {"cli": ("--frames",), "python": ("frames", "n_frames")},
}

#: Names that share a word with a concept but say something else: Khachiyan's iterations of the
#: minimum-volume ellipsoid, the pictures of a video, the frames and trajectories a learning-curve fit used.
OTHER_CONCEPTS = {
    ("Ellipsoid", "iterations"),
    ("VideoResult", "frames"),
    ("CurvePoint", "frames"),
    ("CurvePoint", "trajectories"),
}

#: Run in the measured checkout's interpreter path: every visible option string of every command.
_CLI_OPTIONS = """
import argparse, json
from energy_margin.cli.app import build_parser
parser = build_parser()
options = {}
for action in parser._actions:
    if isinstance(action, argparse._SubParsersAction):
        for name, sub in action.choices.items():
            for a in sub._actions:
                if a.option_strings and a.help != argparse.SUPPRESS:
                    options.setdefault(name, []).extend(a.option_strings)
print(json.dumps(options))
"""

_LEARN_DEFAULTS = """
import argparse, json, inspect
from energy_margin.cli.app import build_parser
from energy_margin.learning.margin_model import fit_margin_model
parser = build_parser()
sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["learn"]
python = inspect.signature(fit_margin_model).parameters["kind"].default
print(json.dumps({"cli": sub.get_default("kind"), "python": python}))
"""


def _python_names(package: Path) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """Public parameter and field names -> their annotations' text, and ``progress`` annotations -> places."""
    names: dict[str, set[str]] = {}
    progress: dict[str, set[str]] = {}
    for path in sorted(package.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        where = str(path.relative_to(package))
        for node in ast.walk(tree):
            annotated: list[tuple[str, ast.expr | None]] = []
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not node.name.startswith("_"):
                arguments = [*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs]
                annotated = [(a.arg, a.annotation) for a in arguments if a.arg not in ("self", "cls")]
            elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                annotated = [
                    (item.target.id, item.annotation)
                    for item in node.body
                    if isinstance(item, ast.AnnAssign)
                    and isinstance(item.target, ast.Name)
                    and (node.name, item.target.id) not in OTHER_CONCEPTS
                ]
            for name, annotation in annotated:
                text = ast.unparse(annotation) if annotation is not None else ""
                names.setdefault(name, set()).add(text)
                if name == "progress":
                    kind = "Progress" if "Progress" in text else "callback" if "Callable" in text else "bool"
                    progress.setdefault(kind, set()).add(where)
    return names, progress


def _settings_files(package: Path) -> dict[str, list[str]]:
    """Each run's settings file, by its form: ``<command>.json`` or ``<command>_settings.json``."""
    forms: dict[str, list[str]] = {}
    pattern = re.compile(
        r'(?:SETTINGS_FILE|settings_file|CONFIG_FILE|CONTROL_FILE|CALIBRATION_FILE)\s*=\s*"([\w.]+\.json)"'
    )
    for path in sorted(package.rglob("*.py")):
        for name in pattern.findall(path.read_text(encoding="utf-8")):
            form = "<command>_settings.json" if name.endswith("_settings.json") else "<command>.json"
            forms.setdefault(form, []).append(name)
    return {form: sorted(set(found)) for form, found in forms.items()}


#: Qualifiers of a name that say whose value it is, not what it is.
QUALIFIERS = ("lambda_", "score_", "margin_", "max_")


def _base(spelling: str) -> str:
    """``--lambda-expansions`` and ``lambda_expansions`` -> ``expansions`` (``n_frames`` stays itself)."""
    name = spelling.lstrip("-").replace("-", "_")
    for qualifier in QUALIFIERS:
        if name.startswith(qualifier):
            return name[len(qualifier) :]
    return name


def measure(root: Path) -> dict[str, Any]:
    """The spellings of every concept in the checkout ``root``."""
    package = root / "src" / "energy_margin"
    options = run_on(root, _CLI_OPTIONS) or {}
    visible = {option for found in options.values() for option in found}
    names, progress = _python_names(package)
    concepts: dict[str, Any] = {}
    for concept, spellings in CONCEPTS.items():
        cli = [s for s in spellings["cli"] if s in visible]
        python = []
        for name in spellings["python"]:
            texts = names.get(name, set())
            if concept != "expansions per frame":
                texts = {t for t in texts if t.startswith("int")}
            if texts:
                python.append(name)
        # A qualified spelling (--lambda-expansions: the lambda sweep's expansions) is its base name.
        bases = sorted({_base(name) for name in [*cli, *python]})
        python_bases = {_base(name) for name in python}
        concepts[concept] = {
            "cli": cli,
            "python": python,
            "bases": bases,
            "names": len(bases),
            "python_names": len(python_bases),
        }
    concepts["progress"] = {"python": sorted(progress), "names": len(progress)}
    settings = _settings_files(package)
    concepts["settings file"] = {"files": settings, "names": len(settings)}
    learn = run_on(root, _LEARN_DEFAULTS)
    if learn is not None:
        concepts["learned margin kind (default)"] = {**learn, "names": len({learn["cli"], learn["python"]})}
    return {"concepts": concepts, "names": sum(entry["names"] for entry in concepts.values()), "count": len(concepts)}


def main() -> None:
    args = checkout_arguments(__doc__)
    root = args.root
    commit = commit_of(root)
    figures = {"commit": commit, **measure(root)}
    print(f"checkout {root} at {commit}")
    for concept, entry in figures["concepts"].items():
        detail = {key: value for key, value in entry.items() if key != "names"}
        print(f"  {concept:<32} {entry['names']} names  {json.dumps(detail, sort_keys=True)}")
    print(f"  {figures['names']} names for {figures['count']} concepts")
    write_figures(args.out, figures)


if __name__ == "__main__":
    main()
