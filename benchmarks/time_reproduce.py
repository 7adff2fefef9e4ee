"""Time ``energy-margin reproduce`` (the quick start's main job) on this machine and write the figures.

Runs the command in a fresh output directory, records the wall time, what the command announced,
the machine, its load before the run, the engine versions and the stages' own times (from the run's
``stages.json``: every stage, their sum, the paper protocol's and the report's), and writes them as
JSON (the README quotes the file through ``tools/figures.py``).

    python benchmarks/time_reproduce.py --out docs/figures/reproduce_full.json
    python benchmarks/time_reproduce.py --quick --out docs/figures/reproduce_quick.json

``--keep DIR`` also copies the reproduction's tables (``table1.json``, ``ablation.json``,
``stages.json``) into DIR, so pages can quote them:

    python benchmarks/time_reproduce.py --out docs/figures/reproduce_full.json --keep docs/figures/reproduce
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from energy_margin.runs.versions import engine_versions

#: The reproduction's own tables, copied by ``--keep``.
KEPT = ("table1.json", "ablation.json", "stages.json")


def cpu_name() -> str:
    """The processor's model name, from ``/proc/cpuinfo`` where there is one."""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def minutes_and_seconds(seconds: float) -> str:
    """``849`` as ``"14 min 09 s"``."""
    whole = round(seconds)
    return f"{whole // 60} min {whole % 60:02d} s"


def timed_run(command: str, load_before: float, wall: float, versions: dict[str, str]) -> dict[str, object]:
    """What a timed command's results file records: the command, date, machine, load, versions, wall time."""
    return {
        "command": command,
        "date": datetime.date.today().isoformat(),
        "machine": f"{os.cpu_count()}-core {cpu_name()}",
        "load_before": round(load_before, 2),
        "load_after": round(os.getloadavg()[0], 2),
        "versions": versions,
        "wall_s": round(wall, 1),
        "wall": minutes_and_seconds(wall),
    }


def stage_figures(stages: list[dict[str, object]]) -> dict[str, object]:
    """The stages of a run's ``stages.json``, their sum and the paper protocol's and the report's, s."""

    def total(chosen: list[dict[str, object]]) -> float:
        return round(sum(float(stage["seconds"]) for stage in chosen), 1)  # type: ignore[arg-type]

    return {
        "stages": [{"stage": stage["stage"], "seconds": round(float(stage["seconds"]), 2)} for stage in stages],  # type: ignore[arg-type]
        "stages_s": total(stages),
        "paper_protocol_stages_s": total([stage for stage in stages if "paper protocol" in str(stage["stage"])]),
        "report_stage_s": total([stage for stage in stages if str(stage["stage"]).startswith("report")]),
    }


def announced_minutes(announced: str | None) -> float | None:
    """``"75 s"``, ``"27 min"`` or ``"1.5 h"`` in minutes, to one decimal (``None`` stays ``None``)."""
    if announced is None:
        return None
    value, unit = announced.split()
    return round(float(value) * {"s": 1 / 60, "min": 1.0, "h": 60.0}[unit], 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="time reproduce --quick")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    parser.add_argument("--keep", type=Path, default=None, help="a folder to copy the reproduction's tables into")
    args = parser.parse_args()
    command = ["energy-margin", "reproduce", *(["--quick"] if args.quick else []), "--workers", str(args.workers)]
    executable = shutil.which("energy-margin") or str(Path(sys.executable).with_name("energy-margin"))
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as work:
        started = time.perf_counter()
        found = subprocess.run(
            [executable, *command[1:], "--out", str(Path(work) / "reproduce")],
            capture_output=True,
            text=True,
            check=False,
            env={**os.environ, "ENERGY_MARGIN_PROGRESS": "0"},
        )
        wall = time.perf_counter() - started
        stages_file = Path(work) / "reproduce" / "stages.json"
        stages = json.loads(stages_file.read_text()) if stages_file.is_file() else []
        if found.returncode == 0 and args.keep is not None:
            args.keep.mkdir(parents=True, exist_ok=True)
            for name in KEPT:
                shutil.copyfile(Path(work) / "reproduce" / name, args.keep / name)
    if found.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {found.returncode}: {found.stderr.strip()[-2000:]}")
    announced = re.search(r"expected about ([0-9.]+) (min|s|h)", found.stdout + found.stderr)
    said = None if announced is None else f"{announced.group(1)} {announced.group(2)}"
    figures = {
        **timed_run(" ".join(command), load_before, wall, engine_versions()),
        "announced": said,
        "announced_min": announced_minutes(said),
        **stage_figures(stages),
    }
    args.out.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(figures, indent=2))


if __name__ == "__main__":
    main()
