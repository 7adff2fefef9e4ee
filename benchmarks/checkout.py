"""What the measures of a checkout share: its arguments, its commit, and code run on its sources.

``codebase_measures.py``, ``names_per_concept.py``, ``docs_figures.py`` and ``argument_trace.py``
each read a checkout (this one by default, ``--root`` another, e.g. a worktree of an earlier
commit) and may write their figures as JSON (``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def checkout_arguments(doc: str | None) -> argparse.Namespace:
    """``--root`` (the checkout, resolved) and ``--out`` (a JSON file, or ``None``)."""
    parser = argparse.ArgumentParser(description=(doc or "").split("\n", 1)[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="the checkout")
    parser.add_argument("--out", type=Path, help="write the figures as JSON here")
    args = parser.parse_args()
    args.root = args.root.resolve()
    return args


def commit_of(root: Path) -> str:
    """The short hash of the checkout's ``HEAD`` (empty outside git)."""
    found = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return found.stdout.strip()


def run_on(root: Path, code: str, *, required: bool = False) -> Any:
    """The JSON that ``code`` prints last, run by this interpreter on the checkout's ``src``.

    ``None`` when it fails (``required``: exit with its error instead).
    """
    env = {**os.environ, "PYTHONPATH": str(root / "src")}
    found = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False)
    if found.returncode != 0:
        if required:
            raise SystemExit(f"running on {root} failed:\n{found.stderr[-2000:]}")
        return None
    return json.loads(found.stdout.strip().splitlines()[-1])


def write_figures(path: Path | None, figures: dict[str, Any]) -> None:
    """Write the figures as indented JSON with sorted keys (nothing without ``path``)."""
    if path is not None:
        path.write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n", encoding="utf-8")
