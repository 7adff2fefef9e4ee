"""What the benchmarks that write one results document share: their arguments, its head, writing it.

``converge_ap.py``, ``unseen_sets.py``, ``scooping_results.py``, ``table_one_reference.py``,
``engine_parity.py`` and ``engine_scooping.py`` each generate or import sets under ``--work``
(kept, so a run resumes), analyse them, and write one JSON document to ``--out`` whose first
keys say how, when and where it was measured.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from bench_analysis import machine  # the machine line of the other benchmarks

__all__ = ["document_head", "energy_margin", "work_arguments", "write_document"]


def work_arguments(
    doc: str | None, *, workers: bool = True, work_help: str = "where the sets and their analyses go (resumed)"
) -> argparse.ArgumentParser:
    """A parser with ``--work`` and ``--out`` (both required) and, with ``workers``, ``--workers`` (2)."""
    parser = argparse.ArgumentParser(description=(doc or "").split("\n", 1)[0])
    parser.add_argument("--work", type=Path, required=True, help=work_help)
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    if workers:
        parser.add_argument("--workers", type=int, default=2)
    return parser


def document_head(script: str) -> dict[str, str]:
    """The command that writes the document (``script`` in ``benchmarks/``), today's date and the machine."""
    return {
        "command": f"python benchmarks/{script} --work WORK --out FILE",
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
    }


def write_document(path: Path, document: dict[str, Any]) -> None:
    """Write ``document`` as indented JSON at ``path``, making its folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")


def energy_margin(*arguments: str) -> str:
    """Run ``energy-margin ARGUMENTS`` in this interpreter; its standard output (exit with its error on failure)."""
    command = [sys.executable, "-m", "energy_margin", *arguments]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-2000:]}")
    return done.stdout
