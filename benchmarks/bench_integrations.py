"""Cost of the Gymnasium wrapper on Gymnasium's Pusher-v5: per-step overhead and per-call scoring latency.

Usage::

    python benchmarks/bench_integrations.py [--steps 10000] [--calls 200] [--repeats 7] [--seed 0]
        [--out docs/figures/integrations_cost.json]

Everything runs in this one process, one after another:

* overhead per step with scoring off (``every=0``), with and without recording, against the plain
  environment on the same actions (the ratio is the figure; both sides step the same physics;
  the three are warmed up, then timed in turn, median of ``--repeats`` passes);
* latency per scoring call with the tree at budgets 10 ms and 50 ms (mean, median, 95th
  percentile, maximum, and how often a call kept its budget: the share of calls with ``ms`` at
  most the budget and at most 1.1 x the budget) and the expansions reached, with the scorer's
  reserve for its measured overrun and without it (the tree given the whole budget: before);
* latency per call with a learned margin (a boosted-tree margin model fitted here on a small
  Pusher dataset: episodes of random actions recorded through the wrapper, analysed with 60
  expansions per frame; its accuracy is not the point, its speed is).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine  # the machine line of the other benchmarks

CAPTURE = {"type": "distance", "body": "tips_arm", "max": 0.1}
SUCCESS = {"type": "distance", "body": "goal", "max": 0.1}


def _env(**options: Any) -> Any:
    import gymnasium

    from energy_margin.integrations.gymnasium import MarginWrapper

    env = gymnasium.make("Pusher-v5")
    if options.pop("plain", False):
        return env
    return MarginWrapper(env, objects="object", capture=CAPTURE, success=SUCCESS, **options)


def per_step(env: Any, actions: np.ndarray, seed: int) -> float:
    """Mean wall time of one step over ``actions`` (episodes restarted when they end), microseconds."""
    env.reset(seed=seed)
    started = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return 1e6 * (time.perf_counter() - started) / len(actions)


def latencies(env: Any, calls: int, seed: int) -> list[dict[str, Any]]:
    """The ``info["energy_margin"]`` of ``calls`` scored steps of random actions."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    found = []
    while len(found) < calls:
        _, _, terminated, truncated, info = env.step(rng.uniform(-2, 2, size=7))
        if "energy_margin" in info:
            found.append(info["energy_margin"])
        if terminated or truncated:
            env.reset()
    return found


def summary(name: str, margins: list[dict[str, Any]], budget_ms: float | None) -> dict[str, Any]:
    """Latency and expansions of ``margins`` (``within_*``: shares of calls within the budget, ``None`` without one)."""
    ms = np.array([m["ms"] for m in margins])
    expansions = np.array([m["expansions"] for m in margins])
    return {
        "scorer": name,
        "calls": len(ms),
        "mean_ms": float(ms.mean()),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "max_ms": float(np.max(ms)),
        "within_budget": None if budget_ms is None else float(np.mean(ms <= budget_ms)),
        "within_1_1_budget": None if budget_ms is None else float(np.mean(ms <= 1.1 * budget_ms)),
        "expansions_mean": float(expansions.mean()),
    }


def describe(row: dict[str, Any]) -> str:
    """A printed table row of :func:`summary`."""
    within = "-" if row["within_budget"] is None else f"{row['within_budget']:.3f}"
    kept = "-" if row["within_1_1_budget"] is None else f"{row['within_1_1_budget']:.3f}"
    return (
        f"| {row['scorer']} | {row['calls']} | {row['mean_ms']:.2f} | {row['median_ms']:.2f} | {row['p95_ms']:.2f} | "
        f"{row['max_ms']:.2f} | {within} | {kept} | {row['expansions_mean']:.0f} |"
    )


def learned_model(directory: Path, seed: int) -> Path:
    """A boosted-tree margin model fitted to a small analysed Pusher dataset recorded through the wrapper."""
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import analyze
    from energy_margin.data.dataset import load_dataset
    from energy_margin.data.record import record_dataset
    from energy_margin.integrations.gym_scene import scene_from_environment
    from energy_margin.learning.margin_model import fit_margin_model

    env = _env(every=0, record=True)
    scene = scene_from_environment(env, objects="object", out=directory / "pusher.toml").scene_file
    rng = np.random.default_rng(seed)
    episodes = []
    for episode in range(8):
        env.reset(seed=seed + episode)
        for _ in range(40):
            env.step(rng.uniform(-2, 2, size=7))
        episodes.append(env.save_episode(directory / f"episode_{episode}.npz"))
    record_dataset(scene, episodes, n_frames=8, out=directory / "dataset")
    analyze(directory / "dataset", AnalyzerConfig(expansions=60), seed=seed, workers=1)
    model, _ = fit_margin_model([load_dataset(directory / "dataset")], seed=seed, kind="boosting")
    path = directory / "model.npz"
    model.save(path)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=10_000, help="steps timed for the overhead")
    parser.add_argument("--calls", type=int, default=200, help="scoring calls timed per setting")
    parser.add_argument("--repeats", type=int, default=7, help="timed passes of each setting, in turn")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, help="results file (JSON)")
    args = parser.parse_args()
    try:
        import gymnasium  # noqa: F401
    except ImportError:
        raise SystemExit("bench_integrations needs Gymnasium: pip install 'energy-margin[gymnasium]'") from None
    load_before = os.getloadavg()[0]
    print(f"machine: {machine()}; load average {load_before:.2f} before")
    actions = np.random.default_rng(args.seed).uniform(-2, 2, size=(args.steps, 7))
    # The three environments are built first, warmed up by one pass, then timed in turn (plain,
    # wrapped, recording, plain, ...) so that a slower period of the machine hits all three.
    envs = {"plain": _env(plain=True), "off": _env(every=0), "recording": _env(every=0, record=True)}
    for env in envs.values():
        per_step(env, actions[:200], args.seed)
    times: dict[str, list[float]] = {name: [] for name in envs}
    for _ in range(args.repeats):
        for name, env in envs.items():
            times[name].append(per_step(env, actions, args.seed))
    plain, off, recording = (statistics.median(times[name]) for name in envs)
    print(f"Gymnasium Pusher-v5, {args.steps} steps, median of {args.repeats} runs taken in turn")
    print("| setting | us per step | ratio to the plain environment |")
    print("|---|---|---|")
    steps = [
        {"setting": "plain environment", "us_per_step": plain, "ratio": 1.0},
        {"setting": "MarginWrapper, scoring off", "us_per_step": off, "ratio": off / plain},
        {"setting": "MarginWrapper, scoring off, recording", "us_per_step": recording, "ratio": recording / plain},
    ]
    for row in steps:
        print(f"| {row['setting']} | {row['us_per_step']:.1f} | {row['ratio']:.3f} |")
    print()
    print(f"Scoring latency per call ({args.calls} calls each, every=1, random actions)")
    print("| scorer | calls | mean ms | median ms | p95 ms | max ms | <= budget | <= 1.1 x budget | expansions |")
    print("|---|---|---|---|---|---|---|---|---|")
    from energy_margin.integrations.live_model import LiveModelScorer

    reserve = LiveModelScorer.tree_budget
    calls = []
    for budget in (0.01, 0.05):
        margins = latencies(_env(every=1, budget_s=budget, max_expansions=100_000), args.calls, args.seed)
        calls.append(summary(f"tree, budget {budget * 1000:.0f} ms", margins, budget * 1000))
        print(describe(calls[-1]))
        # Before: the tree given the whole budget, no reserve for the call's own overrun.
        LiveModelScorer.tree_budget = lambda self: self.options.budget_s  # type: ignore[method-assign]
        try:
            margins = latencies(_env(every=1, budget_s=budget, max_expansions=100_000), args.calls, args.seed)
        finally:
            LiveModelScorer.tree_budget = reserve  # type: ignore[method-assign]
        calls.append(summary(f"tree, budget {budget * 1000:.0f} ms, no reserve", margins, budget * 1000))
        print(describe(calls[-1]))
    with tempfile.TemporaryDirectory() as scratch:
        try:
            model = learned_model(Path(scratch), args.seed)
        except EnergyMarginError as error:
            print(f"| learned margin | could not be fitted: {error} |")
        else:
            margins = latencies(_env(every=1, model=model), args.calls, args.seed)
            calls.append(summary("learned margin (boosting)", margins, None))
            print(describe(calls[-1]))
    if args.out:
        run = {"steps": args.steps, "calls": args.calls, "repeats": args.repeats, "seed": args.seed}
        results = {"machine": machine(), "load_before": load_before, "load_after": os.getloadavg()[0],
                   "settings": run, "steps": steps, "calls": calls}  # fmt: skip
        args.out.write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
