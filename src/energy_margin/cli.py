"""The ``energy-margin`` command line: generate, analyze, evaluate, perturb, budget, reproduce, check."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from energy_margin import __version__
from energy_margin.errors import EnergyMarginError

PROG = "energy-margin"


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return value


def _positive_int(text: str) -> int:
    value = _non_negative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return value


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    parser = _Parser(prog=PROG, description="Energy-margin robustness of multi-object manipulation.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    generate = commands.add_parser("generate", help="record scripted roll-outs as a dataset")
    generate.add_argument("--task", required=True, help="registered task name (e.g. pushing)")
    generate.add_argument("--objects", type=int, required=True, help="objects per scene (>= 1)")
    generate.add_argument("--trajectories", type=int, default=20, help="roll-outs (default 20)")
    generate.add_argument("--frames", type=int, default=10, help="frames per roll-out (default 10)")
    generate.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    generate.add_argument("--engine", default="mujoco", help="physics engine (default mujoco)")
    generate.add_argument("--out", required=True, help="dataset directory to create")
    generate.add_argument("--overwrite", action="store_true", help="replace an existing directory")
    generate.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=JSON",
        help="override a task setting, e.g. --set drive_jitter=0.1",
    )

    analyze = commands.add_parser("analyze", help="score every frame of a dataset")
    analyze.add_argument("dataset", help="dataset directory")
    analyze.add_argument(
        "--iterations",
        type=_non_negative_int,
        default=None,
        help="EST expansions per frame (default 300 when --nodes is absent)",
    )
    analyze.add_argument("--nodes", type=_non_negative_int, default=None, help="tree nodes per frame")
    analyze.add_argument("--cost", choices=("wrench", "energy"), default="wrench", help="incremental cost")
    analyze.add_argument(
        "--lambda",
        dest="likelihood_lambda",
        type=_non_negative_float,
        default=None,
        help="softmax inverse temperature, 1/J (default: the task's)",
    )
    analyze.add_argument("--workers", type=_positive_int, default=1, help="parallel workers (default 1)")
    analyze.add_argument(
        "--executor", choices=("local", "ray"), default="local", help="local process pool (default) or Ray"
    )
    analyze.add_argument("--address", default=None, help="Ray cluster address (default: start a local Ray)")
    analyze.add_argument("--seed", type=_non_negative_int, default=0, help="seed (default 0)")
    analyze.add_argument("--engine", default="mujoco", help="physics engine (default mujoco)")
    analyze.add_argument("--overwrite", action="store_true", help="replace scores of another configuration")
    analyze.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    analyze.add_argument(
        "--method", choices=("est", "montecarlo", "rrt"), default="est", help="tree method (default est)"
    )
    analyze.add_argument(
        "--batch", type=_positive_int, default=1, help="expansions per mujoco.rollout round (default 1)"
    )
    analyze.add_argument("--threads", type=_positive_int, default=1, help="mujoco.rollout threads (default 1)")

    reproduce = commands.add_parser("reproduce", help="Table I, the Fig. 2 ablation and an HTML report")
    reproduce.add_argument("--quick", action="store_true", help="small sets: a few minutes on 2 cores")
    reproduce.add_argument(
        "--out", default=None, help="output directory (default runs/reproduce or runs/reproduce-quick)"
    )
    reproduce.add_argument("--workers", type=_positive_int, default=2, help="parallel workers (default 2)")
    reproduce.add_argument("--engine", default="mujoco", help="physics engine (default mujoco)")
    reproduce.add_argument("--seed", type=_non_negative_int, default=0, help="seed (default 0)")

    check = commands.add_parser("check", help="list every problem of a dataset (and its scores)")
    check.add_argument("dataset", help="dataset directory")
    check.add_argument("--no-overlaps", action="store_true", help="skip the (simulated) overlap check")
    analyze.add_argument(
        "--projection",
        choices=("objects", "ellipsoid"),
        default="objects",
        help="EST density features: every object's centre, or the ellipsoid of the centres (default objects)",
    )

    reference = commands.add_parser(
        "import-reference", help="convert the authors' published frames, labels and scores into a dataset"
    )
    reference.add_argument("path", help="a task folder of the authors' data, e.g. .../planepush-10objects")
    reference.add_argument("--out", required=True, help="dataset directory to create")
    reference.add_argument(
        "--scores",
        default=None,
        metavar="SUBDIR",
        help="sub-folder of the ao_est.csv to import ('.' = the folder itself; default original/original-data)",
    )
    reference.add_argument("--no-scores", action="store_true", help="import frames and labels only")
    reference.add_argument(
        "--drive",
        choices=("nominal", "coast"),
        default="nominal",
        help="pusher during analysis: this project's nominal drive (default) or coasting as in the authors' planner",
    )
    reference.add_argument("--overwrite", action="store_true", help="replace an existing directory")

    evaluate = commands.add_parser("evaluate", help="Average Precision against the labels")
    evaluate.add_argument("dataset", help="dataset directory with scores.csv")
    evaluate.add_argument("--json", action="store_true", help="print one JSON object")
    evaluate.add_argument("--capture-window", type=_non_negative_int, default=0, help="k-hat (default 0)")
    evaluate.add_argument("--success-frames", type=_positive_int, default=3, help="k-bar (default 3)")
    evaluate.add_argument(
        "--weights", choices=("linear", "uniform"), default="linear", help="trajectory success weights (default linear)"
    )
    budget = commands.add_parser("budget", help="AP and runtime against the expansion budget per method")
    budget.add_argument("dataset", help="dataset directory")
    budget.add_argument(
        "--budgets", type=_positive_int, nargs="+", default=[10, 30, 100, 300, 1000], help="iterations per frame"
    )
    budget.add_argument(
        "--methods", nargs="+", choices=("est", "montecarlo", "rrt"), default=["est", "montecarlo", "rrt"]
    )
    budget.add_argument("--workers", type=_positive_int, default=1, help="local worker processes")
    budget.add_argument("--seed", type=_non_negative_int, default=0, help="seed (default 0)")
    budget.add_argument("--bootstrap", type=_non_negative_int, default=1000, help="trajectory resamples (default 1000)")
    budget.add_argument("--out", default=None, help="summary CSV (default DIR/budget/budget.csv; JSON, PNG beside)")
    budget.add_argument("--batch", type=_positive_int, default=1, help="expansions per mujoco.rollout round")
    budget.add_argument("--threads", type=_positive_int, default=1, help="mujoco.rollout threads")
    evaluate.add_argument(
        "--compare",
        nargs="+",
        default=None,
        metavar="DIR",
        help="scored perturbed copies of the dataset (or their parent directory): print Table I",
    )

    perturb = commands.add_parser("perturb", help="perturbed copies: objects resampled inside their ellipsoid")
    perturb.add_argument("dataset", help="true-state dataset directory")
    perturb.add_argument("--repeats", type=_positive_int, default=5, help="perturbed copies (default 5)")
    perturb.add_argument("--seed", type=_non_negative_int, default=0, help="seed (default 0)")
    perturb.add_argument("--out", required=True, help="parent directory of the copies OUT/1 ... OUT/R")
    perturb.add_argument(
        "--tolerance", type=_non_negative_float, default=5e-4, help="largest accepted penetration, m (default 5e-4)"
    )
    perturb.add_argument(
        "--keep-orientation", action="store_true", help="keep recorded orientations (default: identity, as the paper)"
    )
    perturb.add_argument("--overwrite", action="store_true", help="replace existing copies")
    return parser


def _task_overrides(pairs: list[str]) -> dict[str, object]:
    overrides: dict[str, object] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key:
            raise EnergyMarginError(f"--set expects KEY=JSON, got {pair!r}")
        try:
            overrides[key] = json.loads(text)
        except json.JSONDecodeError:
            raise EnergyMarginError(f"--set {key}: {text!r} is not valid JSON") from None
    return overrides


def _run(args: argparse.Namespace) -> int:
    if args.command == "generate":
        from energy_margin.dataset import generate_dataset

        bar = _bar(args.trajectories, "generate")
        try:
            dataset = generate_dataset(
                args.task,
                n_objects=args.objects,
                n_trajectories=args.trajectories,
                n_frames=args.frames,
                seed=args.seed,
                out=args.out,
                engine=args.engine,
                task_config=_task_overrides(args.set),
                overwrite=args.overwrite,
                progress=bar.update,
            )
        finally:
            bar.close()
        labels = dataset.arrays
        print(
            f"dataset {args.out}: {dataset.n_trajectories} trajectories x {dataset.n_frames} frames, "
            f"{dataset.n_objects} objects; captured frames {labels['captured'].mean():.2f}, "
            f"successful trajectories {dataset.success_labels().mean():.2f}"
        )
        return 0
    if args.command == "analyze":
        from energy_margin.analysis import AnalyzerConfig, analyze

        iterations = args.iterations if args.iterations is not None or args.nodes is not None else 300
        try:
            config = AnalyzerConfig(
                iterations=iterations,
                nodes=args.nodes,
                cost=args.cost,
                likelihood_lambda=args.likelihood_lambda,
                engine=args.engine,
                method=args.method,
                batch=args.batch,
                threads=args.threads,
                projection=args.projection,
            )
        except ValueError as error:
            raise EnergyMarginError(str(error)) from None
        path = analyze(
            args.dataset,
            config,
            seed=args.seed,
            workers=args.workers,
            executor=args.executor,
            address=args.address,
            overwrite=args.overwrite,
            progress=not args.no_progress,
        )
        print(f"wrote {path}")
        return 0
    if args.command == "reproduce":
        from energy_margin.reproduce import ReproduceConfig, reproduce
        from energy_margin.sim import ENGINES

        if args.engine not in ENGINES:
            raise EnergyMarginError(f"unknown engine {args.engine!r}; choose one of {', '.join(ENGINES)}")
        _require_matplotlib()
        plan = ReproduceConfig.create(quick=args.quick, workers=args.workers, engine=args.engine, seed=args.seed)
        out = args.out or ("runs/reproduce-quick" if args.quick else "runs/reproduce")
        index = reproduce(out, plan)
        print(f"report: {index}")
        print(f"tables: {index.parent.parent / 'table1.md'}, {index.parent.parent / 'ablation.md'}")
        return 0
    if args.command == "check":
        from energy_margin.validation import check_dataset

        warnings: list = []
        problems = check_dataset(args.dataset, overlaps=not args.no_overlaps, scores=None, warnings=warnings)
        for warning in warnings:
            print(f"warning: {warning}")
        for problem in problems:
            print(problem)
        if problems:
            raise EnergyMarginError(f"{len(problems)} problem(s) in {args.dataset}")
        print(f"{args.dataset}: ok")
        return 0
    if args.command == "evaluate" and args.compare:
        from energy_margin.evaluate import format_table
        from energy_margin.robustness import compare_perturbed, format_robustness_table

        result = compare_perturbed(
            args.dataset,
            args.compare,
            capture_window=args.capture_window,
            success_frames=args.success_frames,
            weights=args.weights,
        )
        text = format_table(result) + "\n\n" + format_robustness_table(result)
        print(json.dumps(result, sort_keys=True) if args.json else text)
        return 0
    if args.command == "perturb":
        from energy_margin.perturb import perturb_dataset

        paths = perturb_dataset(
            args.dataset,
            repeats=args.repeats,
            seed=args.seed,
            out=args.out,
            tolerance=args.tolerance,
            keep_orientation=args.keep_orientation,
            overwrite=args.overwrite,
        )
        print(f"wrote {len(paths)} perturbed copies: {', '.join(str(p) for p in paths)}")
        return 0
    if args.command == "import-reference":
        from energy_margin.reference import import_reference

        dataset = import_reference(
            args.path,
            args.out,
            scores=args.scores,
            with_scores=not args.no_scores,
            overwrite=args.overwrite,
            drive=args.drive,
        )
        scored = " with their scores" if (dataset.path is not None and (dataset.path / "scores.csv").exists()) else ""
        print(
            f"dataset {args.out}: {dataset.metadata['task']}, {dataset.n_trajectories} trajectories x "
            f"{dataset.n_frames} frames, {dataset.n_objects} objects{scored}"
        )
        return 0
    if args.command == "evaluate":
        from energy_margin.evaluate import evaluate, format_table

        result = evaluate(
            args.dataset,
            capture_window=args.capture_window,
            success_frames=args.success_frames,
            weights=args.weights,
        )
        print(json.dumps(result, sort_keys=True) if args.json else format_table(result))
        return 0
    if args.command == "budget":
        from energy_margin.analysis import AnalyzerConfig
        from energy_margin.budget import budget_sweep
        from energy_margin.budget import format_table as budget_table

        try:
            base = AnalyzerConfig(batch=args.batch, threads=args.threads)
        except ValueError as error:
            raise EnergyMarginError(str(error)) from None
        rows = budget_sweep(
            args.dataset,
            budgets=args.budgets,
            methods=args.methods,
            workers=args.workers,
            seed=args.seed,
            bootstrap=args.bootstrap,
            out=args.out,
            base=base,
        )
        print(budget_table(rows))
        return 0
    raise AssertionError(args.command)


class _Bar:
    def __init__(self, total: int, desc: str) -> None:
        self._bar = None
        if sys.stderr.isatty() or os.environ.get("ENERGY_MARGIN_PROGRESS") == "1":
            from tqdm import tqdm

            self._bar = tqdm(total=total, desc=desc, unit="traj")

    def update(self, count: int) -> None:
        if self._bar is not None:
            self._bar.update(count)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _bar(total: int, desc: str) -> _Bar:
    return _Bar(total if isinstance(total, int) and total > 0 else 0, desc)


def _require_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise EnergyMarginError("the report needs matplotlib: pip install 'energy-margin[plot]'") from None


def _one_line(message: str) -> str:
    """Collapse whitespace so an error is always reported on a single line."""
    return " ".join(message.split())


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return _run(args)
    except EnergyMarginError as error:
        print(f"{PROG}: error: {_one_line(str(error))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; run the same command again to resume", file=sys.stderr)
        return 130
    except Exception as error:
        if os.environ.get("ENERGY_MARGIN_DEBUG"):
            raise
        print(
            f"{PROG}: error: {type(error).__name__}: {error} (set ENERGY_MARGIN_DEBUG=1 for details)", file=sys.stderr
        )
        return 1


if __name__ == "__main__":
    sys.exit(main())
