"""AP against time per frame: every budget from one tree per frame, and stopping rules replayed on it.

Usage::

    python benchmarks/time_to_ap.py --task pushing --objects 10 --seeds 61 62 [--trajectories 10]
        [--frames 10] [--method est] [--max-expansions 1000] [--workers 2] [--analysis-seed 0]
        [--out docs/figures/time_to_ap_pushing.json]
    python benchmarks/time_to_ap.py --scene examples/pushing/pushing.toml --seeds 61 62 ...

EST and RRT only: Monte Carlo lays its roll-outs out by the whole budget (N / L roll-outs grown
layer by layer), so its first n expansions are not a tree of n expansions (``energy-margin budget``
analyses each budget of it apart).

For each generation seed a dataset is generated, then every frame's tree is grown once to
``--max-expansions`` with the frame's own seed (``analyze``'s per-frame seeds for
``--analysis-seed``). Every 5 expansions both scores of the tree so far are recorded with the
growth time up to there (the time spent recording is left out; the final scoring of a frame is
timed once and added to every budget). The tree at n expansions is a tree of n expansions, grown
with the random stream of the whole budget: the controls are drawn in blocks whose size the
budget sets, so its scores are those of ``analyze --expansions n`` in distribution, not to the
bit; every budget is compared with 300 expansions on the same trees (paired). That recording
leaves the tree as it is is checked on the first frame of every set (its scores at the whole
budget are ``analyze``'s).

It prints and writes, per set and budget, the AP of ``evaluate``'s questions (capture k̂ = 0 and
2, success from the last 3 frames and from the first half, linear weights) and the mean seconds per
frame; the budgets' AP against 300 expansions; and the replay of the adaptive budget's rules
(``--converge TOL``, projected and window, decided by ``analyze``'s own rule every 25 expansions)
on the same traces, and of the projected rule on the scores' logit, which counts a move of a
score near 0 or 1 as much as one near 0.5 (a candidate for near-certain frames, not an
``analyze`` option).
The first ``--choose`` seeds' sets choose, the others check: the cheapest budget that holds every
AP within 0.01 of 300 expansions on every choosing set is reported with its AP change on the
checking ones.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.convergence import frame_seeds, score_field, scores_settled
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, analyze_frame
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.metrics import question_aps
from energy_margin.planning import CostField
from energy_margin.tasks import get_task

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine as describe_machine  # the machine line of the other benchmarks

__all__: list[str] = []

BUDGETS = (10, 20, 30, 50, 100, 150, 200, 300, 500, 1000)
REFERENCE = 300
STEP = 5
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")
TOLERANCE = 0.01
#: Replayed stopping rules and their tolerances: ``analyze --converge TOL --converge-rule RULE``
#: (``projected-reached``: the projected rule once the success score has left 0), and the
#: projected rule on the scores' logit (a candidate, not in ``analyze``).
RULES = {
    "projected": (0.01, 0.02, 0.03),
    "window": (0.01, 0.02, 0.03),
    "projected-logit": (0.05, 0.1, 0.2),
    "projected-reached": (0.01, 0.02, 0.03),
}
_DATASET: Dataset | None = None


class _Trace:
    """The stop callback that never stops: both scores and the growth time every STEP expansions."""

    def __init__(self, dataset: Dataset, trajectory: int, frame: int, lam: float) -> None:
        self.task, self.root, self.lam = dataset.task, dataset.frame(trajectory, frame), lam
        self.started = time.perf_counter()
        self.spent = 0.0
        self.rows: list[tuple[int, float, float, float]] = []

    def __call__(self, field: CostField) -> bool:
        entered = time.perf_counter()
        capture, success = score_field(self.task, self.root, field, self.lam)
        self.rows.append((field.expansions, capture, success, entered - self.started - self.spent))
        self.spent += time.perf_counter() - entered
        return False


def _init(path: str) -> None:
    global _DATASET
    _DATASET = load_dataset(path)


def _trace_frame(job: tuple[int, int, int, int, str]) -> dict[str, Any]:
    trajectory, frame, seed, max_expansions, method = job
    dataset = _DATASET
    assert dataset is not None
    lam = dataset.task.config.likelihood_lambda
    trace = _Trace(dataset, trajectory, frame, lam)
    config = AnalyzerConfig(expansions=max_expansions, method=method, capture_gate="none")
    scores, field = analyze_frame(
        dataset.task,
        dataset.frame(trajectory, frame),
        friction=float(dataset.arrays["friction"][trajectory]),
        drive=dataset.arrays["drive"][trajectory],
        seed=seed,
        config=config,
        stop=trace,
        check_every=STEP,
        start_time=float(dataset.arrays["frame_time"][trajectory, frame]),
    )
    scoring = time.perf_counter()
    score_field(dataset.task, dataset.frame(trajectory, frame), field, lam)
    scoring = time.perf_counter() - scoring
    rows = [*trace.rows, (scores.expansions, scores.capture_score, scores.success_score, trace.rows[-1][3])]
    return {"trajectory": trajectory, "frame": frame, "rows": rows, "scoring_s": scoring}


def _at(rows: list[tuple[int, float, float, float]], budget: int) -> tuple[float, float, float]:
    """Scores and growth time of the trace at ``budget`` expansions (the last row at or before it)."""
    found = [row for row in rows if row[0] <= budget]
    _, capture, success, seconds = found[-1]
    return capture, success, seconds


def _replay(rows: list[tuple[int, float, float, float]], rule: str, tolerance: float, budget: int) -> int:
    """Expansions at which the adaptive budget's rule stops, checked as ``analyze --converge`` checks it."""
    defaults = AnalyzerConfig()
    scale = _logit if rule == "projected-logit" else float
    history = [
        (n, scale(capture), scale(success))
        for n, capture, success, _ in rows
        if n % defaults.converge_every == 0 and n <= budget
    ]
    for i, (now, _, _) in enumerate(history):
        settled = scores_settled(
            history[: i + 1],
            remaining=budget - now,
            tolerance=tolerance,
            window=defaults.converge_window,
            rule="projected" if rule == "projected-logit" else rule,
        )
        if settled:
            return now
    return budget


def _logit(score: float) -> float:
    """log(s / (1 - s)), the score clipped to [1e-3, 1 - 1e-3]: a change near 0 or 1 counts as much as one near 0.5."""
    clipped = min(max(score, 1e-3), 1 - 1e-3)
    return float(np.log(clipped / (1 - clipped)))


def _ap(dataset: Dataset, capture: np.ndarray, success: np.ndarray) -> dict[str, float | None]:
    found = question_aps(dataset, capture, success, capture_window=0, success_frames=3, weights="linear")
    return {key: found[key] for key in QUESTIONS}


def measure_set(args: argparse.Namespace, seed: int, workdir: Path) -> dict[str, Any]:
    """Generate one set, trace every frame, and the AP of every budget and rule."""
    task = get_task("scene", {"scene_file": args.scene}) if args.scene else get_task(args.task)
    out = workdir / f"set{seed}"
    generate_dataset(
        task,
        n_objects=None if args.scene else args.objects,
        n_trajectories=args.trajectories,
        n_frames=args.frames,
        seed=seed,
        out=out,
    )
    dataset = load_dataset(out)
    seeds = frame_seeds(args.analysis_seed, dataset.n_trajectories * dataset.n_frames)
    jobs = [
        (t, k, seeds[t * dataset.n_frames + k], args.max_expansions, args.method)
        for t in range(dataset.n_trajectories)
        for k in range(dataset.n_frames)
    ]
    with multiprocessing.get_context("spawn").Pool(args.workers, initializer=_init, initargs=(str(out),)) as pool:
        traces = pool.map(_trace_frame, jobs, chunksize=1)
    # Recording never changes the tree: the last row is what analyze gives at the whole budget.
    config = AnalyzerConfig(expansions=args.max_expansions, method=args.method, capture_gate="none")
    direct = FrameAnalyzer(dataset, config, args.analysis_seed)(0)
    if tuple(traces[0]["rows"][-1][1:3]) != (direct["capture_score"], direct["success_score"]):
        raise SystemExit(f"set {seed}: the traced tree's scores are not analyze's at {args.max_expansions} expansions")
    shape = (dataset.n_trajectories, dataset.n_frames)
    budgets = []
    for budget in [b for b in BUDGETS if b <= args.max_expansions]:
        capture, success, seconds = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        for trace in traces:
            index = (trace["trajectory"], trace["frame"])
            capture[index], success[index], seconds[index] = _at(trace["rows"], budget)
            seconds[index] += trace["scoring_s"]
        budgets.append(
            {"expansions": budget, "seconds_per_frame": float(seconds.mean()), **_ap(dataset, capture, success)}
        )
    rules = []
    for rule, tolerances in RULES.items():
        for tolerance in tolerances:
            capture, success, seconds, spent = (np.zeros(shape) for _ in range(4))
            for trace in traces:
                index = (trace["trajectory"], trace["frame"])
                stop = _replay(trace["rows"], rule, tolerance, REFERENCE)
                capture[index], success[index], seconds[index] = _at(trace["rows"], stop)
                seconds[index] += trace["scoring_s"]
                spent[index] = stop
            rules.append(
                {
                    "rule": rule,
                    "tolerance": tolerance,
                    "mean_expansions": float(spent.mean()),
                    "seconds_per_frame": float(seconds.mean()),
                    **_ap(dataset, capture, success),
                }
            )
    return {"seed": seed, "n_frames": int(np.prod(shape)), "budgets": budgets, "rules": rules}


def holds(row: dict[str, Any], reference: dict[str, Any]) -> bool:
    """Whether every AP of ``row`` is within TOLERANCE of (or above) the reference's."""
    return all(
        row[key] is None or reference[key] is None or row[key] >= reference[key] - TOLERANCE for key in QUESTIONS
    )


def choose(sets: list[dict[str, Any]], n_choosing: int) -> dict[str, Any]:
    """The cheapest budget holding every AP on every choosing set, and what it does on the checking sets."""
    choosing, checking = sets[:n_choosing], sets[n_choosing:]

    def reference(entry: dict[str, Any]) -> dict[str, Any]:
        # 300 expansions, or the largest budget traced when that is fewer.
        budget = min(REFERENCE, max(row["expansions"] for row in entry["budgets"]))
        return next(row for row in entry["budgets"] if row["expansions"] == budget)

    chosen = REFERENCE
    for budget in sorted(row["expansions"] for row in choosing[0]["budgets"]):
        rows = [next(row for row in entry["budgets"] if row["expansions"] == budget) for entry in choosing]
        if all(holds(row, reference(entry)) for row, entry in zip(rows, choosing, strict=True)):
            chosen = budget
            break
    checks = []
    for entry in checking:
        row = next(row for row in entry["budgets"] if row["expansions"] == chosen)
        ref = reference(entry)
        changes = {key: None if row[key] is None or ref[key] is None else row[key] - ref[key] for key in QUESTIONS}
        checks.append({"seed": entry["seed"], "holds": holds(row, ref), "change": changes})
    return {"chosen_expansions": chosen, "checks": checks}


TITLES = {
    "capture_ap": "capture, k̂ = 0",
    "capture_ap_window2": "capture, k̂ = 2",
    "success_ap": "success, last 3 frames",
    "success_ap_first_half": "success, first half",
}


def plot(document: dict[str, Any], path: Path, title: str) -> None:
    """AP of each question against seconds per frame: one line per set, the rules as markers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(QUESTIONS), figsize=(4 * len(QUESTIONS), 3.4), sharex=True)
    for axis, key in zip(axes, QUESTIONS, strict=True):
        for entry in document["sets"]:
            rows = [row for row in entry["budgets"] if row[key] is not None]
            if not rows:
                continue
            line = axis.plot(
                [row["seconds_per_frame"] for row in rows],
                [row[key] for row in rows],
                marker="o",
                ms=3,
                label=f"seed {entry['seed']}",
            )[0]
            for row in rows:
                if row["expansions"] in (30, 100, 300, 1000):
                    axis.annotate(str(row["expansions"]), (row["seconds_per_frame"], row[key]), fontsize=7)
            rule = next(r for r in entry["rules"] if r["rule"] == "projected" and r["tolerance"] == 0.02)
            if rule[key] is not None:
                axis.plot(rule["seconds_per_frame"], rule[key], marker="*", ms=9, color=line.get_color())
        axis.set_xscale("log")
        axis.set_title(TITLES[key], fontsize=9)
        axis.set_xlabel("seconds per frame")
    axes[0].set_ylabel("AP")
    axes[0].legend(fontsize=7)
    figure.suptitle(f"{title}: AP against time per frame (numbers: expansions; star: --converge 0.02)", fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def summary(sets: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per budget and per rule over the sets: mean time, mean AP and the worst AP change against 300 expansions."""
    rows: list[dict[str, Any]] = []
    labels = [("budget", str(row["expansions"])) for row in sets[0]["budgets"]]
    labels += [("rule", f"{row['rule']} {row['tolerance']}") for row in sets[0]["rules"]]
    for kind, label in labels:
        found = []
        for entry in sets:
            budgets = {str(row["expansions"]): row for row in entry["budgets"]}
            rules = {f"{row['rule']} {row['tolerance']}": row for row in entry["rules"]}
            reference = budgets[str(min(REFERENCE, max(row["expansions"] for row in entry["budgets"])))]
            found.append(((budgets if kind == "budget" else rules)[label], reference))
        row: dict[str, Any] = {
            "setting": label if kind == "rule" else f"{label} expansions",
            "mean_expansions": float(np.mean([r.get("mean_expansions", r.get("expansions")) for r, _ in found])),
            "seconds_per_frame": float(np.mean([r["seconds_per_frame"] for r, _ in found])),
        }
        for key in QUESTIONS:
            pairs = [(r[key], ref[key]) for r, ref in found if r[key] is not None and ref[key] is not None]
            row[key] = float(np.mean([value for value, _ in pairs])) if pairs else None
            row[f"{key}_worst_change"] = min(value - ref for value, ref in pairs) if pairs else None
        worst = [row[f"{key}_worst_change"] for key in QUESTIONS if row[f"{key}_worst_change"] is not None]
        row["worst_change"] = min(worst) if worst else None
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="pushing")
    parser.add_argument("--scene", help="a scene file instead of a built-in task")
    parser.add_argument("--objects", type=int, default=10)
    parser.add_argument(
        "--seeds", type=int, nargs="+", required=True, help="generation seeds: the first --choose choose"
    )
    parser.add_argument("--choose", type=int, default=1, help="how many of the seeds' sets choose the budget")
    parser.add_argument("--trajectories", type=int, default=10)
    parser.add_argument("--frames", type=int, default=10)
    # Monte Carlo lays its roll-outs out by the whole budget (N / L roll-outs, grown layer by
    # layer), so its first n expansions are not a tree of n expansions: it is not traced.
    parser.add_argument("--method", default="est", choices=("est", "rrt"))
    parser.add_argument("--max-expansions", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--analysis-seed", type=int, default=0)
    parser.add_argument("--out", type=Path)
    parser.add_argument("--figure", type=Path, help="a PNG of AP against time per frame")
    args = parser.parse_args()
    machine = f"{describe_machine()}; load average {os.getloadavg()[0]:.2f} before"
    print(f"machine: {machine}", flush=True)
    settings = {key: value for key, value in vars(args).items() if key not in ("out", "figure")}
    sets = _done_sets(args.out, settings)
    with tempfile.TemporaryDirectory() as workdir:
        for seed in args.seeds:
            entry = next((done for done in sets if done["seed"] == seed), None)
            if entry is None:
                entry = measure_set(args, seed, Path(workdir))
                sets.append(entry)
                # Written after every set: an interrupted run resumes with the sets it finished.
                _write(args.out, {"machine": machine, "settings": settings, "sets": sets, "choice": None})
            _print_set(entry, args.method)
    chosen = choose(sets, args.choose) if len(sets) > args.choose else None
    if chosen:
        print(
            f"\ncheapest budget holding every AP within {TOLERANCE} of {REFERENCE} on sets "
            f"{args.seeds[: args.choose]}: {chosen['chosen_expansions']}; on the checking sets: {chosen['checks']}"
        )
    document = {"machine": machine, "settings": settings, "sets": sets, "choice": chosen, "summary": summary(sets)}
    _write(args.out, document)
    if args.figure:
        name = Path(args.scene).stem if args.scene else f"{args.task}, {args.objects} objects"
        plot({"sets": sets}, args.figure, f"{name} ({args.method})")
        print(f"wrote {args.figure}")


def _done_sets(path: Path | None, settings: dict[str, Any]) -> list[dict[str, Any]]:
    """The sets an earlier run with the same settings (but the seeds) wrote to ``path``.

    A set written before a rule of RULES existed is measured again (its traces are not kept).
    """
    if path is None or not path.exists():
        return []
    earlier = json.loads(path.read_text())
    same = {key: value for key, value in earlier.get("settings", {}).items() if key not in ("seeds", "choose")}
    if same != {key: value for key, value in settings.items() if key not in ("seeds", "choose")}:
        raise SystemExit(f"{path} holds a run with other settings: give another --out or remove it")
    rules = {(rule, tolerance) for rule, tolerances in RULES.items() for tolerance in tolerances}
    return [
        entry
        for entry in earlier["sets"]
        if entry["seed"] in settings["seeds"] and {(row["rule"], row["tolerance"]) for row in entry["rules"]} == rules
    ]


def _write(path: Path | None, document: dict[str, Any]) -> None:
    if path is None:
        return
    partial = path.with_suffix(".partial")
    partial.write_text(json.dumps(document, indent=2) + "\n")
    partial.replace(path)


def _print_set(entry: dict[str, Any], method: str) -> None:
    print(f"\nset {entry['seed']} ({entry['n_frames']} frames), {method}:")
    print("| expansions | s / frame | capture k̂ = 0 | capture k̂ = 2 | success, last 3 | success, first half |")
    print("|---:|---:|---:|---:|---:|---:|")
    for row in entry["budgets"] + entry["rules"]:
        label = row.get("expansions") or f"{row['rule']} {row['tolerance']} ({row['mean_expansions']:.0f})"
        cells = " | ".join("–" if row[key] is None else f"{row[key]:.3f}" for key in QUESTIONS)
        print(f"| {label} | {row['seconds_per_frame']:.3f} | {cells} |", flush=True)


if __name__ == "__main__":
    main()
