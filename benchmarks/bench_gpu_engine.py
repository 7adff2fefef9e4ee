"""The ``mujoco-warp`` engine against C MuJoCo: parity of the scores and AP, and frames per second.

Parity (``--parity``): one generated set (``--task``, ``--objects``, ``--trajectories`` x 10
frames, generation seed ``--seed``) is analysed twice with the same seed and the same batched
expansion (``--batch`` expansions a round, so both grow their trees the same way): on C MuJoCo
(``mujoco.rollout``, one process) and on MuJoCo Warp on ``--device``, a roll-out's trees grown in
lockstep. It prints and writes the AP of every question of ``evaluate`` on each engine, their
difference, the correlation of the two engines' scores, and frames per second of each.

Throughput (``--throughput``): frames per second of MuJoCo Warp on ``--device`` against the
expansions per round (``--batches``) and the objects per scene (``--object-counts``), with the
device's memory in use, beside C MuJoCo on every CPU core of the machine (a process pool of
``os.cpu_count()`` workers, one frame at a time at the default ``batch`` 1: its fastest).

Both sides do different work where said: float32 against float64 physics, Warp's constraint
solver against MuJoCo's; every propagation of both starts from a zero solver warm start.

    python benchmarks/bench_gpu_engine.py --parity --device cpu --trajectories 6 --out docs/figures/gpu_parity_cpu.json
    python benchmarks/bench_gpu_engine.py --throughput --device cuda --out gpu_throughput.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.executors import make_executor
from energy_margin.analysis.frame import FRAMES_TOGETHER, AnalyzerConfig
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.metrics import question_aps
from energy_margin.runs.versions import engine_versions

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine  # the machine line of the other benchmarks

QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")


def _generate(task: str, objects: int, trajectories: int, seed: int, workdir: Path) -> Dataset:
    out = workdir / f"{task}-{objects}x{trajectories}-{seed}"
    if not (out / "dataset.json").exists():
        generate_dataset(task, n_objects=objects, n_trajectories=trajectories, n_frames=10, seed=seed, out=out,
                         overwrite=True)  # fmt: skip
    return load_dataset(out)


def _score(dataset: Dataset, config: AnalyzerConfig, *, seed: int, workers: int) -> tuple[dict[str, np.ndarray], float]:
    """Capture and success scores (n_trajectories, n_frames) and the wall time, s."""
    shape = (dataset.n_trajectories, dataset.n_frames)
    capture, success = np.zeros(shape), np.zeros(shape)
    started = time.perf_counter()
    indices = list(range(shape[0] * shape[1]))
    for row in make_executor("local", workers=workers).run(dataset, config, seed, indices):
        capture[row["trajectory"], row["frame"]] = row["capture_score"]
        success[row["trajectory"], row["frame"]] = row["success_score"]
    return {"capture": capture, "success": success}, time.perf_counter() - started


def _aps(dataset: Dataset, scores: dict[str, np.ndarray]) -> dict[str, float | None]:
    found = question_aps(dataset, scores["capture"], scores["success"], capture_window=0, success_frames=3,
                         weights="linear")  # fmt: skip
    return {key: found[key] for key in QUESTIONS}


APs = dict[str, float | None]


def _ap_rows(first: APs, second: APs, names: tuple[str, str]) -> list[dict[str, Any]]:
    """One row per question: the AP of both sides under ``names`` and ``second - first``."""
    rows = []
    for key in QUESTIONS:
        a, b = first[key], second[key]
        rows.append(
            {"question": key, names[0]: a, names[1]: b, "difference": None if a is None or b is None else b - a}
        )
    return rows


def parity(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    dataset = _generate(args.task, args.objects, args.trajectories, args.seed, workdir)
    frames = dataset.n_trajectories * dataset.n_frames
    common = {"expansions": args.expansions, "batch": args.batch, "contacts": args.contacts}
    reference, reference_s = _score(dataset, AnalyzerConfig(**common), seed=args.analysis_seed, workers=1)
    warp_config = AnalyzerConfig(**common, engine="mujoco-warp", device=args.device)
    warp, warp_s = _score(dataset, warp_config, seed=args.analysis_seed, workers=1)
    rows = _ap_rows(_aps(dataset, reference), _aps(dataset, warp), ("mujoco", "mujoco_warp"))
    correlation = {
        kind: float(np.corrcoef(reference[kind].ravel(), warp[kind].ravel())[0, 1])
        if reference[kind].std() > 0 and warp[kind].std() > 0
        else None
        for kind in ("capture", "success")
    }
    return {
        "set": {
            "task": args.task,
            "objects": args.objects,
            "trajectories": args.trajectories,
            "frames": frames,
            "generation_seed": args.seed,
            "analysis_seed": args.analysis_seed,
        },
        "analysis": common,
        "ap": rows,
        "largest_ap_difference": max(
            (abs(float(r["difference"])) for r in rows if r["difference"] is not None), default=None
        ),
        "score_correlation": correlation,
        "mean_absolute_score_difference": {
            kind: float(np.abs(reference[kind] - warp[kind]).mean()) for kind in ("capture", "success")
        },
        "frames_per_second": {"mujoco": frames / reference_s, "mujoco_warp": frames / warp_s},
        "device": args.device,
        # Every frame's scores on both engines, (trajectories, frames) each: where the engines differ.
        "frame_scores": {
            engine: {kind: scores[kind].tolist() for kind in ("capture", "success")}
            for engine, scores in (("mujoco", reference), ("mujoco_warp", warp))
        },
    }


def seed_noise(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    """How far C MuJoCo's own AP moves with the analysis seed: the yardstick of a parity difference."""
    dataset = _generate(args.task, args.objects, args.trajectories, args.seed, workdir)
    config = AnalyzerConfig(expansions=args.expansions, batch=args.batch, contacts=args.contacts)
    first = _aps(dataset, _score(dataset, config, seed=args.analysis_seed, workers=1)[0])
    second = _aps(dataset, _score(dataset, config, seed=args.analysis_seed + 1, workers=1)[0])
    rows = _ap_rows(first, second, ("seed", "next_seed"))
    return {"analysis_seeds": [args.analysis_seed, args.analysis_seed + 1], "ap": rows}


#: The recorded root state of a frame: what the Warp engine holds in float32 on the device.
ROOT_ARRAYS = ("object_pos", "object_quat", "object_vel", "robot_q", "robot_v")


def float32_roots(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    """How far C MuJoCo's AP moves when only the frames' roots are rounded to float32.

    The Warp engine starts every propagation from a float32 copy of its state and steps in float32;
    rounding the recorded frames alone, with everything else float64 and the same seed, measures how
    sensitive each question is to the smallest change float32 makes: a lower bound of the engine's
    own arithmetic difference, on C MuJoCo.
    """
    dataset = _generate(args.task, args.objects, args.trajectories, args.seed, workdir)
    arrays = dict(dataset.arrays)
    for name in ROOT_ARRAYS:
        arrays[name] = np.asarray(arrays[name], dtype=np.float32).astype(np.float64)
    rounded = Dataset(dataset.path, dataset.metadata, arrays)
    config = AnalyzerConfig(expansions=args.expansions, batch=args.batch, contacts=args.contacts)
    plain_scores = _score(dataset, config, seed=args.analysis_seed, workers=1)[0]
    rounded_scores = _score(rounded, config, seed=args.analysis_seed, workers=1)[0]
    rows = _ap_rows(_aps(dataset, plain_scores), _aps(dataset, rounded_scores), ("float64", "float32_roots"))
    return {
        "analysis_seed": args.analysis_seed,
        "ap": rows,
        "mean_absolute_score_difference": {
            kind: float(np.abs(plain_scores[kind] - rounded_scores[kind]).mean()) for kind in ("capture", "success")
        },
    }


def host_side(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    """The host's share of a batched call: building every propagation's controls, no physics.

    The fastest of five calls of ``--rows`` propagations of a frame of the set, each the task's longest, through the
    batched propagator with its physics replaced by nothing: what is left is the Python that
    evaluates the scripted command of every propagation and packs its control vector, which a GPU
    cannot hide. It bounds the frames per second of any engine behind the batched propagator.
    """
    dataset = _generate(args.task, args.objects, args.trajectories, args.seed, workdir)
    task = dataset.task
    simulator = task.make_simulator(dataset.n_objects, float(dataset.arrays["friction"][0]), dataset.arrays["drive"][0])
    simulator.reset(dataset.frame(0, 0))
    propagator = simulator.rollout_propagator(1)
    propagator._roll_to = lambda initial, *rest, **options: initial  # any version of its signature
    k = args.rows
    limits = task.wrench_limits(simulator.scene)
    steps = max(1, int(limits.max_duration / simulator.timestep))
    rng = np.random.default_rng(0)
    control_steps = max(1, round(task.control_period / simulator.timestep)) if task.control_period else None
    inputs = (
        task,
        np.broadcast_to(dataset.arrays["drive"][0], (k, dataset.arrays["drive"].shape[1])),
        np.repeat(propagator.current_state()[None], k, axis=0),
        np.zeros(k),
        rng.uniform(-1, 1, (k, *limits.max_wrench.shape)) * limits.max_wrench,
        np.full(k, steps),
        control_steps,
    )
    took = []
    for _ in range(5):  # the fastest of five calls: the call only, its inputs made before
        started = time.perf_counter()
        propagator.propagate(*inputs)
        took.append(time.perf_counter() - started)
    per_row = min(took) / k
    per_frame = per_row * args.expansions
    return {"rows": k, "steps_per_propagation": steps, "control_steps": control_steps,
            "host_us_per_propagation": per_row * 1e6, "host_s_per_frame": per_frame,
            "frames_per_second_ceiling": 1.0 / per_frame, "expansions": args.expansions}  # fmt: skip


def _device_memory(device: str) -> dict[str, float] | None:
    if device != "cuda":
        return None
    import warp as wp

    cuda = wp.get_device("cuda")
    memory = {"total_gib": cuda.total_memory / 2**30, "free_gib": cuda.free_memory / 2**30}
    high = getattr(wp, "get_mempool_used_mem_high", None)
    if high is not None:
        memory["pool_high_gib"] = high(cuda) / 2**30  # the most Warp's memory pool held so far
    return memory


def throughput(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    rows = []
    for objects in args.object_counts:
        dataset = _generate(args.task, objects, args.trajectories, args.seed, workdir)
        frames = dataset.n_trajectories * dataset.n_frames
        cpu = os.cpu_count() or 1
        _, c_s = _score(dataset, AnalyzerConfig(expansions=args.expansions), seed=args.analysis_seed, workers=cpu)
        for batch in args.batches:
            config = AnalyzerConfig(expansions=args.expansions, batch=batch, engine="mujoco-warp", device=args.device)
            _, warp_s = _score(dataset, config, seed=args.analysis_seed, workers=1)
            worlds = min(batch, args.expansions) * min(frames, FRAMES_TOGETHER)
            row = {"objects": objects, "batch": batch, "frames": frames, "worlds_per_call": worlds,
                   "warp_frames_per_second": frames / warp_s, "mujoco_all_cores_frames_per_second": frames / c_s,
                   "mujoco_workers": cpu, "memory": _device_memory(args.device)}  # fmt: skip
            rows.append(row)
            print(json.dumps(row), flush=True)
    return {"rows": rows, "expansions": args.expansions, "device": args.device}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--parity", action="store_true", help="scores and AP on both engines, one set")
    mode.add_argument("--throughput", action="store_true", help="frames per second against batch and objects")
    mode.add_argument(
        "--host-side", action="store_true", help="the host's Python per propagation of a batched call, no physics"
    )
    mode.add_argument(
        "--float32-roots",
        action="store_true",
        help="C MuJoCo's AP with the frames' roots rounded to float32, added to the --out file of a parity run",
    )
    mode.add_argument(
        "--seed-noise",
        action="store_true",
        help="C MuJoCo's AP at two analysis seeds, added to the --out file of a parity run as seed_noise",
    )
    parser.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    parser.add_argument("--task", default="pushing")
    parser.add_argument("--objects", type=int, default=10)
    parser.add_argument("--object-counts", type=int, nargs="+", default=[5, 10, 20])
    parser.add_argument("--trajectories", type=int, default=10)
    parser.add_argument("--seed", type=int, default=700, help="generation seed (used for nothing else)")
    parser.add_argument("--analysis-seed", type=int, default=0)
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument(
        "--contacts", choices=("recorded", "fast"), default="recorded", help="both engines' contact model (--parity)"
    )
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--batches", type=int, nargs="+", default=[32, 100, 300])
    parser.add_argument("--rows", type=int, default=3200, help="propagations of the --host-side call")
    parser.add_argument("--workdir", type=Path, default=None, help="where the sets are generated (default: a temp dir)")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        workdir = args.workdir if args.workdir is not None else Path(temporary)
        workdir.mkdir(parents=True, exist_ok=True)
        if args.seed_noise or args.float32_roots:
            key, column = ("seed_noise", "seed_difference")
            if args.float32_roots:
                key, column = ("float32_roots", "rounded_difference")
            noise = seed_noise(args, workdir) if args.seed_noise else float32_roots(args, workdir)
            print(json.dumps(noise, indent=1))
            if args.out is not None:
                document = json.loads(args.out.read_text())
                command = "python benchmarks/" + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])
                document[key] = {"command": command, **noise}
                moved = {row["question"]: row["difference"] for row in noise["ap"]}
                for row in document.get("ap", []):
                    row[column] = moved.get(row["question"])
                args.out.write_text(json.dumps(document, indent=2) + "\n")
            return
        if args.host_side:
            result = host_side(args, workdir)
            print(json.dumps(result, indent=1))
        else:
            result = parity(args, workdir) if args.parity else throughput(args, workdir)
    document = {
        "command": "python benchmarks/" + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "machine": machine(),
        "versions": engine_versions("mujoco-warp"),
        **result,
    }
    if args.parity:
        print(f"{'question':<24}{'mujoco':>10}{'mujoco-warp':>13}{'difference':>12}")
        for row in document["ap"]:
            cells = [f"{row[key]:.3f}" if row[key] is not None else "-" for key in ("mujoco", "mujoco_warp")]
            diff = f"{row['difference']:+.3f}" if row["difference"] is not None else "-"
            print(f"{row['question']:<24}{cells[0]:>10}{cells[1]:>13}{diff:>12}")
        print("score correlation", document["score_correlation"], "frames/s", document["frames_per_second"])
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(document, indent=2) + "\n")


if __name__ == "__main__":
    main()
