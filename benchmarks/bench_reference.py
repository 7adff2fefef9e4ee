"""The authors' own code and energy-margin on the same frames, in one run, interleaved.

Usage::

    python benchmarks/bench_reference.py [--frames 20] [--block 5] [--start 0] [--expansions 300]
        [--seed 0] [--authors-venv DIR] [--data DIR] [--json FILE] [--set KEY=JSON] [--analyzer KEY=JSON]

Their side is their unchanged planner (pomp AO-EST over PyBullet, ``time_frames.py`` from
``../shared/reference/authors-code``) in a virtual environment with their pinned requirements:
``--authors-venv`` names one, otherwise one is created under ``.authors-venv/`` in the project
root (ignored by git) the first time. Our side is :func:`energy_margin.analyze_frame` on the same
frames imported with ``import-reference`` (MuJoCo, one process). Frames run in blocks that
alternate between the two, so a change of machine load hits both alike. The per-frame time of
both is the planner's own timer: tree growth plus scoring, without building the world. Without
``../shared`` (or when their environment cannot be made) it prints one ``skip:`` line and exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "reference"
AUTHORS = SHARED / "authors-code"
FRAMES = SHARED / "energy_margin_workshop" / "planepush-10objects"
DEFAULT_VENV = ROOT / ".authors-venv"
FRAME_LINE = re.compile(
    r"^FRAME data_id=(\d+) .*?capture_score=([0-9.eE+-]+) success_score=([0-9.eE+-]+) runtime_s=([0-9.]+)"
)


def skip(reason: str) -> None:
    print(f"skip: {reason}")
    sys.exit(0)


def authors_python(venv: Path | None) -> Path:
    """The interpreter of an environment with the authors' requirements, made if needed."""
    if venv is not None:
        python = venv / "bin" / "python"
        if not python.exists():
            skip(f"--authors-venv {venv} has no bin/python")
        return python
    python = DEFAULT_VENV / "bin" / "python"
    marker = DEFAULT_VENV / ".complete"
    if marker.exists():
        return python
    print(f"creating {DEFAULT_VENV} with {AUTHORS / 'requirements.lock'} (once)", file=sys.stderr)
    shutil.rmtree(DEFAULT_VENV, ignore_errors=True)
    try:
        subprocess.run([sys.executable, "-m", "venv", str(DEFAULT_VENV)], check=True, capture_output=True)
        subprocess.run(
            [str(python), "-m", "pip", "install", "-q", "-r", str(AUTHORS / "requirements.lock")],
            check=True,
            capture_output=True,
        )
    except (OSError, subprocess.CalledProcessError) as error:
        shutil.rmtree(DEFAULT_VENV, ignore_errors=True)
        detail = error.stderr.decode(errors="replace").strip().splitlines()[-1:] if hasattr(error, "stderr") else []
        skip(f"cannot create the authors' environment ({' '.join(detail) or error})")
    marker.write_text("ok\n")
    return python


def run_theirs(python: Path, start: int, count: int, iterations: int, seed: int, workdir: Path) -> dict[int, dict]:
    command = [
        str(python),
        str(AUTHORS / "time_frames.py"),
        str(count),
        "--data-dir",
        str(FRAMES),
        "--start",
        str(start),
        "--iters",
        str(iterations),
        "--seed",
        str(seed),
        "--workdir",
        str(workdir),
    ]
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        last = (result.stderr.strip().splitlines() or ["no output"])[-1]
        skip(f"the authors' time_frames.py failed: {last}")
    rows = {}
    for line in result.stdout.splitlines():
        match = FRAME_LINE.match(line)
        if match:
            rows[int(match[1])] = {
                "capture_score": float(match[2]),
                "success_score": float(match[3]),
                "runtime_s": float(match[4]),
            }
    return rows


def frame_rows(theirs: dict[int, dict], ours: dict[int, dict], frames: list[int]) -> list[dict[str, float | int]]:
    """One record per frame scored by both sides: each side's time and scores, ours with its expansions."""
    return [
        {
            "frame": index,
            "theirs_s": theirs[index]["runtime_s"],
            "ours_s": ours[index]["runtime_s"],
            "their_capture": theirs[index]["capture_score"],
            "our_capture": ours[index]["capture_score"],
            "their_success": theirs[index]["success_score"],
            "our_success": ours[index]["success_score"],
            "our_expansions": ours[index]["expansions"],
        }
        for index in frames
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20, help="frames to score on each side (default 20)")
    parser.add_argument("--block", type=int, default=5, help="frames per alternation (default 5)")
    parser.add_argument("--start", type=int, default=0, help="first frame (row of their CSV)")
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--authors-venv", type=Path, default=None)
    parser.add_argument("--json", type=Path, default=None, help="also write every row and the summary here")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="our task setting")
    parser.add_argument("--analyzer", action="append", default=[], metavar="KEY=JSON", help="our AnalyzerConfig field")
    args = parser.parse_args()
    if not FRAMES.is_dir() or not (AUTHORS / "time_frames.py").is_file():
        skip(f"the authors' code and frames are not at {SHARED} (../shared/reference from the project root)")
    python = authors_python(args.authors_venv)

    from mujoco import __version__ as mujoco_version

    # The machine line of the other benchmarks (run from benchmarks/, so it is importable).
    from bench_analysis import machine
    from energy_margin import AnalyzerConfig, analyze_frame
    from energy_margin.analysis.frame import frame_seeds
    from energy_margin.cli.common import task_overrides
    from energy_margin.data.reference import import_reference
    from energy_margin.errors import EnergyMarginError
    from energy_margin.sim import make_simulator
    from energy_margin.tasks import get_task, with_contacts

    try:
        task_config = task_overrides(args.set)
        analyzer = task_overrides(args.analyzer, option="--analyzer")
    except EnergyMarginError as error:
        raise SystemExit(f"bench_reference.py: {error}") from None
    scratch = Path(tempfile.mkdtemp(prefix="bench-reference-"))
    try:
        dataset = import_reference(FRAMES, scratch / "frames", with_scores=False)
        try:
            task = get_task("pushing", {**dataset.task.config.to_dict(), **task_config})
            config = AnalyzerConfig(expansions=args.expansions, **analyzer)  # type: ignore[arg-type]
        except (EnergyMarginError, TypeError, ValueError) as error:
            raise SystemExit(f"bench_reference.py: {error}") from None
        total = dataset.n_trajectories * dataset.n_frames
        seeds = frame_seeds(args.seed, total)
        end = min(args.start + args.frames, total)
        theirs: dict[int, dict] = {}
        ours: dict[int, dict] = {}
        began = time.monotonic()
        load_before = os.getloadavg()
        for block_start in range(args.start, end, args.block):
            count = min(args.block, end - block_start)
            theirs.update(run_theirs(python, block_start, count, args.expansions, args.seed, scratch / "theirs"))
            for index in range(block_start, block_start + count):
                # Their row i is trajectory i // K, frame i % K (their CSV is trajectory-major).
                trajectory, frame = divmod(index, dataset.n_frames)
                friction = float(dataset.arrays["friction"][trajectory])
                drive = dataset.arrays["drive"][trajectory]
                # The scene of the analysis's contact model (``--analyzer contacts='"fast"'``).
                scene = with_contacts(task, config.contacts).build_scene(dataset.n_objects, friction, drive)
                simulator = make_simulator(scene)
                scores, _ = analyze_frame(
                    task,
                    dataset.frame(trajectory, frame),
                    friction=friction,
                    drive=drive,
                    seed=seeds[index],
                    config=config,
                    start_time=float(dataset.arrays["frame_time"][trajectory, frame]),
                    simulator=simulator,
                )
                ours[index] = {
                    "capture_score": scores.capture_score,
                    "success_score": scores.success_score,
                    "runtime_s": scores.runtime_s,
                    "physics_s": scores.physics_s,
                    "expansions": scores.expansions,
                }
        elapsed = time.monotonic() - began
        load_after = os.getloadavg()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)

    frames = sorted(set(theirs) & set(ours))
    if not frames:
        skip("no frame was scored by both sides")
    print(f"machine: {machine()}; load average {load_before[0]:.2f} before, {load_after[0]:.2f} after")
    print(
        f"frames {frames[0]}..{frames[-1]} of {FRAMES.name} ({len(frames)}), {args.expansions} iterations, "
        f"blocks of {args.block} alternating, {elapsed:.0f} s in all; ours: {config}; task overrides {task_config}"
    )
    print()
    print("| frame | theirs [s] | ours [s] | their capture | our capture | their success | our success |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for index in frames:
        a, b = theirs[index], ours[index]
        print(
            f"| {index} | {a['runtime_s']:.3f} | {b['runtime_s']:.3f} | {a['capture_score']:.3f} | "
            f"{b['capture_score']:.3f} | {a['success_score']:.3f} | {b['success_score']:.3f} |"
        )
    their_mean = statistics.fmean(theirs[i]["runtime_s"] for i in frames)
    our_mean = statistics.fmean(ours[i]["runtime_s"] for i in frames)
    physics = statistics.fmean(ours[i]["physics_s"] for i in frames)
    print()
    print(f"theirs: {their_mean:.3f} s per frame; ours: {our_mean:.3f} s per frame (physics {physics:.3f} s)")
    print(f"ratio (theirs / ours): {their_mean / our_mean:.1f}x")
    if args.json is not None:
        summary = {
            "theirs_s": their_mean,
            "ours_s": our_mean,
            "ratio": their_mean / our_mean,
            "frames": frames,
            "expansions": args.expansions,
            # Below ``expansions`` where the analyzer stops early (``converge``); theirs always run all.
            "ours_expansions_mean": statistics.fmean(ours[i]["expansions"] for i in frames),
            "analyzer": dict(analyzer),
            "task": dict(task_config),
            "machine": machine(),
            "load_before": round(load_before[0], 2),
            "load_after": round(load_after[0], 2),
            "mujoco": mujoco_version,
        }
        rows = frame_rows(theirs, ours, frames)
        document = {"summary": summary, "rows": rows, "theirs": theirs, "ours": ours}
        args.json.write_text(json.dumps(document, indent=2) + "\n")


if __name__ == "__main__":
    main()
