"""Time the test suite as the README's second quick-start command runs it, and write the figures.

Runs ``python -m pytest`` in the project root with this interpreter (the install is not timed),
and records the wall time, the counts pytest reports, the machine, its load before and after,
and the versions, as JSON (the README and docs/index.md quote the file through
``tools/figures.py``):

    python benchmarks/time_tests.py --out docs/figures/test_suite.json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

from energy_margin import __version__
from energy_margin.runs.versions import engine_versions
from time_reproduce import timed_run

__all__: list[str] = []

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ("python", "-m", "pytest")
#: pytest's closing line: ``2019 passed, 5 skipped, 10 warnings in 481.73s``.
COUNT = re.compile(r"(\d+) (passed|failed|skipped|errors?|xfailed|xpassed)")


def counts(summary: str) -> dict[str, int]:
    """The counts of pytest's closing line (``passed``, ``skipped``, ...); those it does not name are absent."""
    return {word.rstrip("s") if word.startswith("error") else word: int(n) for n, word in COUNT.findall(summary)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    found = subprocess.run(
        [sys.executable, *COMMAND[1:], "-p", "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True, check=False
    )
    wall = time.perf_counter() - started
    closing = found.stdout.strip().splitlines()[-1] if found.stdout.strip() else ""
    tally = counts(closing)
    if found.returncode != 0 or "passed" not in tally:
        failed = [line for line in found.stdout.splitlines() if line.startswith(("FAILED", "ERROR"))]
        raise SystemExit(
            "\n".join([f"{' '.join(COMMAND)} exited {found.returncode}: {closing or found.stderr[-2000:]}", *failed])
        )
    versions = {"energy_margin": __version__, **engine_versions()}
    figures = {**timed_run(" ".join(COMMAND), load_before, wall, versions), **tally}
    args.out.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(figures, indent=2))


if __name__ == "__main__":
    main()
