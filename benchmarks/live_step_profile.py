"""Where a live call's time goes in a user's stack: physics steps per expansion, MuJoCo's own stage timers.

Usage (in a virtual environment with the stack, on the MuJoCo version it needs)::

    python benchmarks/live_step_profile.py --stack robosuite|metaworld|pusher [--steps 30] [--budget 0.05]
        [--seed 0] [--out docs/figures/live_step_profile.json]

The stacks are those of ``bench_live_stacks.py`` (the same environments, policies and scene tables);
one environment is scored at the live defaults (``AnalyzerConfig()``: the analysis model, one
expansion at a time) after every step. Around each propagation of the tree it reads MuJoCo's timers
(``MjData.timer``) of the scorer's own ``MjData``, where the propagation steps, and reports, over
the ``--steps`` calls:

* the expansions reached and the call's wall time (medians);
* physics steps per expansion and microseconds per physics step (the timers' step count and time);
* the share of the call spent stepping the physics (wall time around each propagation), and within
  a step the shares of collision detection (broad and narrow phase) and of the constraint solver
  (MuJoCo's timers; MuJoCo 3.3.0, Meta-World's, counts them but records no durations: a dash);
* the *physics ceiling*: the expansions a ``--budget`` call would reach if everything but the
  physics steps cost nothing (budget / (steps per expansion x seconds per step)), and what the rest
  of a call (the tree's own work: reading states, regions, the density estimate) costs per expansion.

``--out`` keeps one row per stack in the file (a later run of a stack replaces its row), each with
the machine line and the settings it ran with.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import mujoco

from energy_margin.analysis.frame import AnalyzerConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_live_stacks import STACKS, machine_line, run_settings, stack_arguments  # the same stacks and options

__all__: list[str] = []

#: MuJoCo's timers read around each call: the whole step and the stages the table splits it into.
TIMERS = {
    "step": mujoco.mjtTimer.mjTIMER_STEP,
    "collision": mujoco.mjtTimer.mjTIMER_POS_COLLISION,
    "constraint": mujoco.mjtTimer.mjTIMER_CONSTRAINT,
}


def _timers(data: Any) -> dict[str, tuple[int, float]]:
    """(calls, seconds) of each timer in :data:`TIMERS` so far."""
    return {name: (int(data.timer[index].number), float(data.timer[index].duration)) for name, index in TIMERS.items()}


def profile(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    """Score ``args.steps`` steps of the stack and account for each call's time."""
    from energy_margin.integrations.gymnasium import MarginWrapper

    make, actor, kwargs = STACKS[args.stack](args.seed, args.steps + 5, workdir)
    wrapper = MarginWrapper(make(), every=1, budget_s=args.budget, seed=args.seed, config=AnalyzerConfig(), **kwargs)
    observation = wrapper.reset(seed=args.seed)[0]
    act = actor(wrapper.env)
    simulator = wrapper.scorer.simulator
    data = simulator.data  # the scorer's own MjData: every propagation of the tree steps here
    spent = {name: 0.0 for name in ("steps", "wall", *TIMERS)}
    step = simulator.step

    def timed_step(*step_args: Any, **step_kwargs: Any) -> Any:
        # Read around each propagation: the tree restores whole states (timers included) between them.
        before = _timers(data)
        started = time.perf_counter()
        result = step(*step_args, **step_kwargs)
        spent["wall"] += time.perf_counter() - started
        after = _timers(data)
        spent["steps"] += after["step"][0] - before["step"][0]
        for name in TIMERS:
            spent[name] += after[name][1] - before[name][1]
        return result

    simulator.step = timed_step  # type: ignore[method-assign]
    expansions: list[int] = []
    call_s: list[float] = []
    for _ in range(args.steps):
        observation, _, terminated, truncated, info = wrapper.step(act(observation))
        scores = info["energy_margin"]
        expansions.append(int(scores["expansions"]))
        call_s.append(float(scores["ms"]) / 1000.0)
        if terminated or truncated:
            raise SystemExit(f"the episode ended before {args.steps} steps: give fewer --steps")
    steps_per_expansion = spent["steps"] / sum(expansions)
    seconds_per_step = spent["wall"] / spent["steps"]
    # MuJoCo 3.3.0 counts its timers' calls but records no durations (no clock is set there).
    timed = spent["step"] > 0.0
    return {
        "stack": args.stack,
        "mujoco": mujoco.__version__,
        "timestep": float(simulator.model.opt.timestep),
        "calls": args.steps,
        "expansions_median": statistics.median(expansions),
        "ms_median": 1000.0 * statistics.median(call_s),
        "steps_per_expansion": steps_per_expansion,
        "us_per_step": 1e6 * seconds_per_step,
        "physics_share": spent["wall"] / sum(call_s),
        "collision_share": spent["collision"] / spent["step"] if timed else None,
        "constraint_share": spent["constraint"] / spent["step"] if timed else None,
        "physics_ceiling": args.budget / (steps_per_expansion * seconds_per_step),
        "other_ms_per_expansion": 1000.0 * (sum(call_s) - spent["wall"]) / sum(expansions),
    }


def _share(share: float | None) -> str:
    return "–" if share is None else f"{share:.0%}"


def main() -> None:
    args = stack_arguments(__doc__, steps=30)
    machine = machine_line()
    with tempfile.TemporaryDirectory() as workdir:
        row = profile(args, Path(workdir))
    print(f"\n{args.stack} (MuJoCo {row['mujoco']}, time step {row['timestep']} s): ", end="")
    print(f"{args.steps} calls of {args.budget} s\n")
    print(
        "| expansions (median) | ms (median) | steps / expansion | µs / step | physics share | collision "
        "| constraint | physics ceiling | other ms / expansion |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    print(
        f"| {row['expansions_median']:.0f} | {row['ms_median']:.1f} | {row['steps_per_expansion']:.1f} | "
        f"{row['us_per_step']:.1f} | {row['physics_share']:.0%} | {_share(row['collision_share'])} | "
        f"{_share(row['constraint_share'])} | {row['physics_ceiling']:.0f} | {row['other_ms_per_expansion']:.3f} |"
    )
    if args.out:
        write_row(args.out, {**row, "machine": machine, **run_settings(args)})
        print(f"wrote {args.out}")


def write_row(path: Path, row: dict[str, Any]) -> None:
    """Put ``row`` into the results file at ``path``, in place of an earlier row of its stack.

    Each stack runs in its own environment, so one file gathers the stacks' rows run by run.
    """
    rows = json.loads(path.read_text())["rows"] if path.exists() else []
    rows = [kept for kept in rows if kept["stack"] != row["stack"]] + [row]
    rows.sort(key=lambda kept: sorted(STACKS).index(kept["stack"]))
    path.write_text(json.dumps({"rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
