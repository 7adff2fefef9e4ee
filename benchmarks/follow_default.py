"""Capture AP of example scenes written without ``capture.follow``: the old default against the new one.

For each scene, a copy without its ``follow = true`` line (written as a new user would) is
generated once, then the same dataset is analysed and evaluated twice: by the code of an earlier
checkout (``--old-src``: before regions followed their robot by default, the region is frozen at the
analysed frame) and by this checkout's code (``--new-src``: the region rides on the robot). The
results go to one JSON file (docs/figures/follow_default.json) with the seeds, sizes and budget.

    python benchmarks/follow_default.py --old-src /path/to/old/src --out docs/figures/follow_default.json

``--resamples N`` adds each question's verdict (``evaluate``'s paired interval); ``--reuse`` keeps
the sets already analysed in ``--work``. ``analysis_s``: the frames' tree time summed from ``scores.csv``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from energy_margin.data.scores_file import load_scores

__all__: list[str] = []

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("examples/fetch/fetch.toml", "examples/pushing/pushing.toml")


def _cli(src: Path, *args: str) -> str:
    """Run ``python -m energy_margin ARGS`` with ``src`` first on the path; its standard output."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    done = subprocess.run(
        [sys.executable, "-m", "energy_margin", *args], env=env, capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise SystemExit(f"energy-margin {' '.join(args)} failed:\n{done.stderr}")
    return done.stdout


def _without_follow(scene: Path, out: Path) -> Path:
    """A copy of ``scene`` without its ``follow = true`` line, the files it names by absolute path."""
    text = scene.read_text()
    lines = [line for line in text.splitlines() if line.strip() != "follow = true"]
    if len(lines) != len(text.splitlines()) - 1:
        raise SystemExit(f"{scene}: expected exactly one 'follow = true' line")
    copied = "\n".join(lines) + "\n"
    # The files it names (its model, a motion's controls) by absolute path.
    absolute = lambda match: f'{match.group(1)} = "{(scene.parent / match.group(2)).resolve()}"'  # noqa: E731
    copied = re.sub(r'^(mjcf|ctrl_file) = "([^"]+)"', absolute, copied, flags=re.M)
    path = out / scene.name
    path.write_text(copied)
    return path


@functools.cache
def _continues(src: Path) -> bool:
    """Whether the code at ``src`` knows ``analyze --continuation`` (asked once per source)."""
    return "--continuation" in _cli(src, "analyze", "--help")


def _analyse(src: Path, dataset: Path, expansions: int, seed: int) -> float:
    """Analyse ``dataset`` with the code at ``src`` (unless it holds scores); its frames' summed tree time, s."""
    if not (dataset / "scores.csv").is_file():
        # The tree's own success score, as the figures were measured (a source that continues the
        # motion by default is told not to; an older one never does).
        own = ["--continuation", "0"] if _continues(src) else []
        _cli(src, "analyze", str(dataset), "--expansions", str(expansions), "--workers", "1", "--seed", str(seed),
             "--no-progress", *own)  # fmt: skip
    return round(float(load_scores(dataset)["runtime_s"].sum()), 1)


def _scores(src: Path, dataset: Path, resamples: int) -> dict[str, Any]:
    """``evaluate`` of ``dataset`` by the code at ``src``: capture AP at k-hat 0, 2 and 4, success AP
    (the last frames and the first half of them), each beside the baselines, with the verdict (the
    margin minus the best baseline, paired interval over trajectories) when ``resamples`` > 0."""
    result: dict[str, Any] = {}
    for window in (0, 2, 4):
        options = ["--capture-window", str(window), "--resamples", str(resamples), "--json"]
        report = json.loads(_cli(src, "evaluate", str(dataset), *options))
        result[f"capture_k{window}"] = _question(report, "capture_ap", "capture_positive_rate")
        if window == 0:  # the success questions do not depend on k-hat
            result["success"] = _question(report, "success_ap", "success_positive_rate")
            result["success_first_half"] = _question(report, "success_ap_first_half", "success_positive_rate")
    return result


def _question(report: dict[str, Any], question: str, positive_rate: str) -> dict[str, Any]:
    """One question of an ``evaluate --json`` report: the margin, each baseline, the rate, the verdict."""
    verdict = report.get("verdict") or {}
    return {
        "margin": report[question],
        **{name: values[question] for name, values in report["baselines"].items()},
        "positive_rate": report[positive_rate],
        **({"verdict": verdict[question]} if question in verdict else {}),
    }


def _commit(src: Path) -> str:
    """The git commit of the checkout holding ``src`` (with ``+`` when its tree has changes)."""
    head = subprocess.run(["git", "-C", str(src), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run(["git", "-C", str(src), "status", "--porcelain", "--", "."], capture_output=True, text=True)
    return head.stdout.strip() + ("+" if dirty.stdout.strip() else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old-src", type=Path, required=True, help="src/ of the checkout before the default")
    parser.add_argument("--new-src", type=Path, default=ROOT / "src", help="src/ of this checkout")
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--trajectories", type=int, default=20)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--seed", type=int, default=11, help="generation seed (the examples use 0, 1, 2 and 202)")
    parser.add_argument("--analysis-seed", type=int, default=0)
    parser.add_argument("--expansions", type=int, default=100)
    parser.add_argument("--work", type=Path, default=ROOT / "runs" / "follow_default")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "follow_default.json")
    parser.add_argument("--resamples", type=int, default=0, help="bootstrap resamples of the verdicts (0: none)")
    parser.add_argument("--reuse", action="store_true", help="keep the sets generated and analysed in --work")
    args = parser.parse_args(argv)
    if args.work.exists() and not args.reuse:
        shutil.rmtree(args.work)
    args.work.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {
        "settings": {
            "trajectories": args.trajectories,
            "frames": args.frames,
            "generation_seed": args.seed,
            "analysis_seed": args.analysis_seed,
            "expansions": args.expansions,
            "workers": 1,
            "resamples": args.resamples,
            "evaluated_by": "the new code, both",
            "scene": "the example with its 'follow = true' line removed",
            "old_code": _commit(args.old_src),
            "new_code": _commit(args.new_src),
        },
        "scenes": {},
    }
    for name in args.scenes:
        scene = _without_follow(ROOT / name, args.work)
        key = scene.stem
        dataset = args.work / f"{key}_data"
        if not (dataset / "dataset.json").is_file():
            _cli(args.new_src, "generate", "--scene", str(scene), "--trajectories", str(args.trajectories),
                 "--frames", str(args.frames), "--seed", str(args.seed), "--out", str(dataset))  # fmt: skip
        entry: dict[str, Any] = {"scene": name}
        for label, src in (("old_default", args.old_src), ("new_default", args.new_src)):
            copy = args.work / f"{key}_{label}"
            if not copy.exists():
                shutil.copytree(dataset, copy)
            seconds = _analyse(src.resolve(), copy, args.expansions, args.analysis_seed)
            # Both evaluated by this checkout's code: the sets differ only in how they were analysed.
            entry[label] = {"analysis_s": seconds, **_scores(args.new_src.resolve(), copy, args.resamples)}
            print(f"{key} {label}: {seconds} s", flush=True)
        results["scenes"][key] = entry
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
