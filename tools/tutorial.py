"""Run the tutorial's lessons: every bash block of a page, in order, in a fresh folder.

The folder stands for the repository root: it links ``examples/`` and runs ``energy-margin`` and
``python`` with the given interpreter. ``tests/test_tutorial.py`` runs each lesson;
``python tools/tutorial.py --out FILE`` times each lesson as a new user would run it (the
interpreter of a fresh clone's environment with ``--python``) and writes the times as JSON.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial"
#: The lessons, in the order of the tutorial, with the packages each needs beyond the core ones.
LESSONS = {
    "own-robot.md": ("gymnasium",),
    "gymnasium.md": ("gymnasium",),
    "demonstrations.md": (),
}


def bash_blocks(page: Path) -> list[str]:
    """The shell commands of a page: the body of each ```bash block, in order."""
    return re.findall(r"^```bash\n(.*?)^```", page.read_text(encoding="utf-8"), flags=re.S | re.M)


def run_lesson(
    page: Path, folder: Path, python: str = sys.executable, *, source: Path | None = None
) -> tuple[int, str]:
    """Run every bash block of ``page`` in ``folder`` (created); the exit status and the output.

    Args:
        page: the lesson's Markdown page.
        folder: an empty folder to run in (it gets ``examples/`` and the shims ``bin/``).
        python: the interpreter whose ``energy_margin`` the lesson runs.
        source: a ``src`` directory to put first on ``PYTHONPATH`` (the package as checked out).

    """
    shims = folder / "bin"
    shims.mkdir(parents=True)
    for command, line in {
        "energy-margin": f'exec "{python}" -m energy_margin "$@"',
        "python": f'exec "{python}" "$@"',
    }.items():
        shim = shims / command
        shim.write_text(f"#!/bin/sh\n{line}\n", encoding="utf-8")
        shim.chmod(0o755)
    work = folder / "root"
    work.mkdir()
    (work / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    env = {**os.environ, "PATH": f"{shims}{os.pathsep}{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg"}
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(source), os.environ.get("PYTHONPATH", "")) if p)
    script = "set -euo pipefail\n" + "\n".join(bash_blocks(page))
    result = subprocess.run(
        ["bash", "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=600, check=False
    )
    return result.returncode, result.stdout[-3000:] + result.stderr[-3000:]


def main() -> None:
    """Time every lesson with ``--python`` and write the times to ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--python", default=sys.executable, help="the interpreter of the environment to time")
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args()
    # The lessons run in other folders: a relative path to the interpreter would not reach it there.
    python = str(Path(args.python).absolute()) if Path(args.python).exists() else args.python
    times: dict[str, float] = {}
    for name in LESSONS:
        with tempfile.TemporaryDirectory() as folder:
            started = time.perf_counter()
            status, output = run_lesson(TUTORIAL / name, Path(folder), python)
            times[name] = round(time.perf_counter() - started, 1)
        if status != 0:
            raise SystemExit(f"{name}: exit {status}\n{output}")
        print(f"{name}: {times[name]:.1f} s")
    figures = {
        "date": datetime.date.today().isoformat(),
        "machine": f"{os.cpu_count()} cores",
        "load_before": round(os.getloadavg()[0], 2),
        "lessons_s": times,
        "total_s": round(sum(times.values()), 1),
    }
    args.out.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
