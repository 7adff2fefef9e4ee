"""Where ``analyze``'s default continues the motion: the pilot's decision at the default settings, per scene.

For every example scene file and both built-in tasks, one set of generation seed 13 (used for
nothing else), ``--trajectories`` x 10 frames, is generated and its pilot grown as ``analyze`` grows
it at the default settings (300 expansions, analysis seed 0, the same per-frame seeds): the
first-half frames of the first five roll-outs, with the tree's own success score. The rule
(:mod:`energy_margin.analysis.continuation_rule`) continues where at least 90 % of them score
success exactly 0. Printed and written: each scene's share, decision and the pilot's seconds.

    python benchmarks/continuation_rule.py --out docs/figures/continuation_rule.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from energy_margin.analysis.continuation_rule import choose, pilot_frames
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer
from energy_margin.runs.versions import engine_versions

sys.path.insert(0, str(Path(__file__).resolve().parent))
from success_continuation import SCENES, TASKS, _generate, _task_options  # the scene sets of that benchmark

__all__: list[str] = []

#: Every example scene file the success-continuation benchmark writes, and both built-in tasks.
DEFAULT_SCENES = ("pushing_scene", "jaco", "fetch", "planar_manipulator", "panda_tray", "gym_pusher", *TASKS)
GENERATION_SEED = 13
ANALYSIS_SEED = 0


def _measure(name: str, folder: Path, trajectories: int) -> dict[str, Any]:
    dataset = _generate(_task_options(name, folder), GENERATION_SEED, trajectories, folder / f"{name}-data")
    # analyze's pilot: the default settings with the tree's own success score, analyze's frame seeds.
    analyzer = FrameAnalyzer(dataset, AnalyzerConfig(continuation=0), ANALYSIS_SEED)
    started = time.perf_counter()
    rows = [analyzer(index) for index in pilot_frames(dataset)]
    seconds = time.perf_counter() - started
    chosen = choose(rows)
    return {**chosen.to_dict(), "pilot_s": seconds, "seconds_per_pilot_frame": seconds / max(1, len(rows))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES), choices=[*SCENES, *TASKS])
    parser.add_argument("--trajectories", type=int, default=5)
    args = parser.parse_args()
    results: dict[str, Any] = {
        "command": "python benchmarks/continuation_rule.py " + " ".join(sys.argv[1:]),
        "generation_seed": GENERATION_SEED,
        "analysis_seed": ANALYSIS_SEED,
        "trajectories": args.trajectories,
        "frames": 10,
        "expansions": AnalyzerConfig().expansions,
        "versions": engine_versions("mujoco"),
        "scenes": {},
    }
    with tempfile.TemporaryDirectory() as folder:
        for name in args.scenes:
            results["scenes"][name] = found = _measure(name, Path(folder), args.trajectories)
            print(
                f"{name:20s} share {found['unreached_share']:.2f} of {found['pilot_frames']} -> continuation "
                f"{found['continuation']:2d} ({found['pilot_s']:.1f} s)",
                flush=True,
            )
    results["rows"] = [{"scene": name, **found} for name, found in results["scenes"].items()]
    args.out.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
