"""Time the tutorial as a new user takes it: a fresh clone, the install, then every lesson's commands.

Clones this repository into a temporary folder, makes a virtual environment there, installs the
package with the versions of ``requirements.lock`` (``.[test]``, what the tutorial asks for), then
runs each lesson's commands with that environment (``tools/tutorial.py``), and writes the wall time
of each step as JSON.

    python benchmarks/time_tutorial.py --out docs/figures/tutorial_time.json
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(command: list[str], cwd: Path) -> float:
    """Run ``command`` in ``cwd``; its wall time, s (a failure stops the benchmark with its output)."""
    started = time.perf_counter()
    found = subprocess.run(command, cwd=cwd, capture_output=True, text=True, check=False)
    if found.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {found.returncode}: {(found.stdout + found.stderr)[-3000:]}")
    return round(time.perf_counter() - started, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args()
    load_before = round(os.getloadavg()[0], 2)
    with tempfile.TemporaryDirectory() as work:
        clone = Path(work) / "energy-margin"
        steps = {"clone": timed(["git", "clone", "-q", str(ROOT), str(clone)], Path(work))}
        steps["venv"] = timed([sys.executable, "-m", "venv", ".venv"], clone)
        steps["install"] = timed([".venv/bin/pip", "install", "-q", "-c", "requirements.lock", ".[test]"], clone)
        lessons = Path(work) / "lessons.json"
        python = str(clone / ".venv" / "bin" / "python")
        timed([python, "tools/tutorial.py", "--python", python, "--out", str(lessons)], clone)
        lesson_times = json.loads(lessons.read_text(encoding="utf-8"))["lessons_s"]
    figures = {
        "date": datetime.date.today().isoformat(),
        "machine": f"{os.cpu_count()} cores",
        "load_before": load_before,
        "load_after": round(os.getloadavg()[0], 2),
        "steps_s": steps,
        "lessons_s": lesson_times,
        "lessons_total_s": round(sum(lesson_times.values()), 1),
        "total_s": round(sum(steps.values()) + sum(lesson_times.values()), 1),
        "note": "the install's time depends on the network and on what pip's cache already holds",
    }
    args.out.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(figures, indent=2))


if __name__ == "__main__":
    main()
