"""Expansions per live call in users' stacks: the full model against the analysis model, one thread and two.

Usage (in a virtual environment with the stack, on the MuJoCo version it needs)::

    python benchmarks/bench_live_stacks.py --stack robosuite|metaworld|pusher [--steps 60] [--budget 0.05]
        [--seed 0] [--out docs/figures/live_stacks_STACK.json]

* ``robosuite``: PickPlace with the Panda arm and the scripted policy of
  ``examples/robosuite_pick_place`` (4 objects, robot held still: ``hold="still"``);
* ``metaworld``: Meta-World's ``push-v3`` with its scripted expert (the Sawyer's hand on mocap);
* ``pusher``: Gymnasium's ``Pusher-v5`` with random actions.

One environment per variant, all made with the same seed and stepped in lockstep with the same
actions, so every variant scores the same states; the variants score one after the other at every
step (``--steps`` scored steps, each with a ``--budget`` second wall-clock budget). Variants, the
first four the live default as it was before each of four changes (each undoes its change and the
later ones; all grow the same trees and give the same scores):
``pruned, before: command every period`` (the robot's held command set again every control period
of the scene, as before it was set once per propagation), ``pruned, before: tree costed at every
check`` (the tree's new nodes costed at every deadline check, as when the deadline was a stopping
rule handed the cost field), ``pruned, before: regions placed with the objects`` (a region that
follows the robot built at each state with the objects written into the kinematics, though no
object moves what it is attached to), ``pruned, before: one region per state`` (a following region
built as one region per tree state rather than one over stacked poses); then ``full``
(``analysis_model="full"``, one expansion at a time), ``pruned`` (the analysis model, the live
default), and both with ``batch=8, threads=2`` (expansions propagated eight at a time through
``mujoco.rollout`` on two threads; the deadline is checked between rounds).
It prints, per variant, the expansions reached (median, mean, range) and the call's wall time
(median, maximum).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import json
import os
import statistics
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.planning.tree import _Growth
from energy_margin.tasks import scene_regions

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine as describe_machine  # the machine line of the other benchmarks

__all__: list[str] = []

ROOT = Path(__file__).resolve().parents[1]
#: The live default before each change, oldest first: each variant undoes its change and the later ones.
EVERY_PERIOD = "pruned, before: command every period"
COSTED = "pruned, before: tree costed at every check"
PLACED = "pruned, before: regions placed with the objects"
ONE_PER_STATE = "pruned, before: one region per state"
BEFORE: dict[str, set[str]] = {
    EVERY_PERIOD: {"every period", "costed", "placed", "one per state"},
    COSTED: {"costed", "placed", "one per state"},
    PLACED: {"placed", "one per state"},
    ONE_PER_STATE: {"one per state"},
}
VARIANTS: dict[str, dict[str, Any]] = {
    EVERY_PERIOD: {"analysis_model": "pruned"},
    COSTED: {"analysis_model": "pruned"},
    PLACED: {"analysis_model": "pruned"},
    ONE_PER_STATE: {"analysis_model": "pruned"},
    "full": {"analysis_model": "full"},
    "pruned": {"analysis_model": "pruned"},
    "full, batch 8, 2 threads": {"analysis_model": "full", "batch": 8, "threads": 2},
    "pruned, batch 8, 2 threads": {"analysis_model": "pruned", "batch": 8, "threads": 2},
}


def _module(name: str, path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def robosuite_stack(seed: int, steps: int, workdir: Path) -> tuple[Callable[[], Any], Callable[[Any], Any], dict]:
    """PickPlace as ``examples/robosuite_pick_place`` makes it; the scene file that example writes."""
    from robosuite.wrappers import GymWrapper

    sys.path.insert(0, str(ROOT / "examples"))
    example = _module("pick_place_example", ROOT / "examples/robosuite_pick_place/pick_place.py")
    policy = example.policy_module()
    probe = example.make_env(seed, steps)
    (workdir / "pick_place.xml").write_text(probe.model.get_xml(), encoding="utf-8")
    scene = workdir / "scene.toml"
    scene.write_text(example.scene_text("pick_place.xml", steps, policy.OBJECTS, policy.GRIP_SITE), encoding="utf-8")
    envs: list[Any] = []

    def make() -> Any:
        env = example.make_env(seed, steps)
        envs.append(env)
        return GymWrapper(env)

    def actor(_: Any) -> Any:
        script = policy.ScriptedPickPlace(envs[0], np.random.default_rng(seed), target="Can")
        return lambda observation: script()  # the script reads the first environment's state

    return make, actor, {"scene": scene, "hold": "still"}


def metaworld_stack(seed: int, steps: int, workdir: Path) -> tuple[Callable[[], Any], Callable[[Any], Any], dict]:
    """Meta-World's push-v3 with its scripted expert."""
    import gymnasium
    import metaworld  # noqa: F401  (registers the environments)
    from metaworld.policies import SawyerPushV3Policy

    del steps, workdir

    def make() -> Any:
        return gymnasium.make("Meta-World/MT1", env_name="push-v3", seed=seed)

    def actor(env: Any) -> Any:
        return SawyerPushV3Policy().get_action

    kwargs = {
        "objects": "obj",
        "capture": {"type": "distance", "site": "endEffector", "max": 0.05},
        "success": {"type": "distance", "site": "goal", "max": 0.05},
    }
    return make, actor, kwargs


def pusher_stack(seed: int, steps: int, workdir: Path) -> tuple[Callable[[], Any], Callable[[Any], Any], dict]:
    """Gymnasium's Pusher-v5 with random actions."""
    import gymnasium

    del steps, workdir

    def make() -> Any:
        return gymnasium.make("Pusher-v5")

    def actor(env: Any) -> Any:
        rng = np.random.default_rng(seed)
        return lambda observation: rng.uniform(-1.0, 1.0, size=env.action_space.shape)

    kwargs = {
        "objects": "object",
        "capture": {"type": "distance", "body": "tips_arm", "max": 0.1},
        "success": {"type": "distance", "body": "goal", "max": 0.1},
    }
    return make, actor, kwargs


STACKS = {"robosuite": robosuite_stack, "metaworld": metaworld_stack, "pusher": pusher_stack}


def measure(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    from energy_margin.integrations.gymnasium import MarginWrapper

    make, actor, kwargs = STACKS[args.stack](args.seed, args.steps + 5, workdir)
    wrappers = {
        name: MarginWrapper(
            make(), every=1, budget_s=args.budget, seed=args.seed, config=AnalyzerConfig(**settings), **kwargs
        )
        for name, settings in VARIANTS.items()
    }
    for name, undone in BEFORE.items():
        task = wrappers[name].scorer.task
        if "every period" in undone:  # the held command set again every control period of the scene
            task.control_period = task.loaded.spec.motion.control_period
        if "placed" in undone:  # every region built with the objects written into the kinematics
            follow = {key: dataclasses.replace(one, placed_by_objects=True) for key, one in task.loaded.follow.items()}
            task.loaded = dataclasses.replace(task.loaded, follow=follow)
    undoing = {name: BEFORE.get(name, set()) for name in VARIANTS}
    observations = [wrapper.reset(seed=args.seed)[0] for wrapper in wrappers.values()]
    act = actor(next(iter(wrappers.values())).env)
    reached: dict[str, list[int]] = {name: [] for name in VARIANTS}
    seconds: dict[str, list[float]] = {name: [] for name in VARIANTS}
    for _ in range(args.steps):
        action = act(observations[0])
        observations = []
        for name, wrapper in wrappers.items():
            with (
                costing_at_every_check("costed" in undoing[name]),
                one_region_per_state("one per state" in undoing[name]),
            ):
                observation, _, terminated, truncated, info = wrapper.step(action)
            observations.append(observation)
            reached[name].append(int(info["energy_margin"]["expansions"]))
            seconds[name].append(float(info["energy_margin"]["ms"]) / 1000.0)
            if terminated or truncated:
                raise SystemExit(f"the episode ended before {args.steps} steps: give fewer --steps")
    rows = []
    for name in VARIANTS:
        rows.append(
            {
                "variant": name,
                "settings": VARIANTS[name],
                "expansions_median": statistics.median(reached[name]),
                "expansions_mean": statistics.mean(reached[name]),
                "expansions_min": min(reached[name]),
                "expansions_max": max(reached[name]),
                "ms_median": 1000 * statistics.median(seconds[name]),
                "ms_max": 1000 * max(seconds[name]),
            }
        )
    return {"stack": args.stack, "rows": rows}


@contextlib.contextmanager
def costing_at_every_check(on: bool) -> Iterator[None]:
    """With ``on``, growth costs the tree's new nodes at every deadline check (reads the cost field).

    As when the deadline was a stopping rule handed the cost field after every expansion; the tree
    and its scores are the same either way (``tests/analysis/test_live.py``).
    """
    if not on:
        yield
        return
    offer = _Growth.offer

    def costing_offer(growth: _Growth, round_: Any, outcomes: Any) -> None:
        offer(growth, round_, outcomes)
        if growth.deadline is not None:
            growth.tree.view(growth.expansions)

    _Growth.offer = costing_offer  # type: ignore[method-assign]
    try:
        yield
    finally:
        _Growth.offer = offer  # type: ignore[method-assign]


@contextlib.contextmanager
def one_region_per_state(on: bool) -> Iterator[None]:
    """With ``on``, a scene's set is built as one region per frame or tree state, never over stacked poses."""
    if not on:
        yield
        return
    stacked = scene_regions.builds_stacked
    scene_regions.builds_stacked = lambda table: False  # type: ignore[assignment]
    try:
        yield
    finally:
        scene_regions.builds_stacked = stacked  # type: ignore[assignment]


def stack_arguments(description: str, *, steps: int) -> argparse.Namespace:
    """The command line of a live-stack benchmark: ``--stack``, ``--steps`` (default ``steps``), ``--budget``,
    ``--seed``, ``--out``."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--stack", choices=sorted(STACKS), required=True)
    parser.add_argument("--steps", type=int, default=steps)
    parser.add_argument("--budget", type=float, default=0.05)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path)
    return parser.parse_args()


def machine_line() -> str:
    """The machine line of the other benchmarks and the load average before the run; printed."""
    machine = f"{describe_machine()}; load average {os.getloadavg()[0]:.2f} before"
    print(f"machine: {machine}")
    return machine


def run_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The settings a results file records: steps, budget, seed."""
    return {"steps": args.steps, "budget_s": args.budget, "seed": args.seed}


def main() -> None:
    args = stack_arguments(__doc__, steps=60)
    machine = machine_line()
    with tempfile.TemporaryDirectory() as workdir:
        results = measure(args, Path(workdir))
    budget_ms = 1000 * args.budget
    print(f"\n{args.stack}: {args.steps} scored steps, {budget_ms:.0f} ms budget per call\n")
    print("| variant | expansions (median) | mean | range | ms (median) | ms (max) |")
    print("|---|---:|---:|---:|---:|---:|")
    for row in results["rows"]:
        print(
            f"| {row['variant']} | {row['expansions_median']:.0f} | {row['expansions_mean']:.1f} | "
            f"{row['expansions_min']}–{row['expansions_max']} | {row['ms_median']:.1f} | {row['ms_max']:.1f} |"
        )
    if args.out:
        figures = {"machine": machine, "settings": run_settings(args), **results}
        args.out.write_text(json.dumps(figures, indent=2) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
