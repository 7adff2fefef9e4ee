"""``energy-margin reproduce``: the paper's Table I, the Fig. 2 ablation and an HTML report."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from energy_margin.cli.common import add_engine, add_overwrite, add_seed, positive_int, require_matplotlib, say_notes

__all__ = [
    "EXAMPLES",
    "LOCKED_MUJOCO",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "locked_engine_note",
    "run",
]

#: The MuJoCo of requirements.lock, with which the quoted figures were made (tests/test_packaging.py holds it).
LOCKED_MUJOCO = "4.0.0"

NAME = "reproduce"
SUMMARY = "reproduce the paper: Table I, the number-of-objects ablation and an HTML report"
EXAMPLES = ("energy-margin reproduce --workers 2", "energy-margin reproduce --quick --out runs/quick")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``reproduce``."""
    parser.add_argument("--quick", action="store_true", help="small sets: a few minutes on 2 cores")
    parser.add_argument("--out", default=None, help="output directory (default runs/reproduce or runs/reproduce-quick)")
    parser.add_argument("--workers", type=positive_int, default=2, help="parallel workers (default 2)")
    add_engine(parser, records=True)
    add_seed(parser)
    add_overwrite(parser, "a reproduction of other settings in --out")


def run(args: argparse.Namespace) -> int:
    """Run every stage (resuming finished ones) and print where the report is."""
    from energy_margin.report.config import ReproduceConfig
    from energy_margin.report.reproduce import reproduce

    require_matplotlib()
    say_notes(locked_engine_note())
    plan = ReproduceConfig.create(quick=args.quick, workers=args.workers, engine=args.engine, seed=args.seed)
    out = args.out or ("runs/reproduce-quick" if args.quick else "runs/reproduce")
    # The command as typed when run from the shell; the equivalent command otherwise.
    invoked = Path(sys.argv[0]).name in ("energy-margin", "__main__.py") and sys.argv[1:2] == ["reproduce"]
    command = shlex.join(["energy-margin", *sys.argv[1:]]) if invoked else None
    index = reproduce(out, plan, command=command, overwrite=args.overwrite)
    print(f"report: {index}")
    print(f"tables: {index.parent.parent / 'table1.md'}, {index.parent.parent / 'ablation.md'}")
    return 0


def locked_engine_note() -> str | None:
    """One line when this MuJoCo is not the locked one the documented figures were made with."""
    import mujoco

    if mujoco.__version__ == LOCKED_MUJOCO:
        return None
    return (
        f"note: the documented figures were made with MuJoCo {LOCKED_MUJOCO} (requirements.lock); this is MuJoCo "
        f"{mujoco.__version__}: scores can differ (install with pip install -c requirements.lock to match them)"
    )
