"""``energy-margin reproduce``: the paper's Table I, the Fig. 2 ablation and a visual report.

Every stage writes files and is skipped or resumed when run again: datasets are regenerated only
when missing, analyses resume from their journals, perturbed copies are kept. The resolved
configuration is saved as ``reproduce.json`` in the output directory.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.errors import EnergyMarginError
from energy_margin.io import atomic_write_text, write_json

#: The paper's Table I and Fig. 2 values, printed beside ours.
PAPER_TABLE_I: dict[str, dict[str, Any]] = {
    "pushing": {
        "n_objects": 10,
        "capture_ap": 1.00,
        "capture_ap_perturbed": (0.96, 0.01),
        "capture_score_error": (-0.04, 0.32),
        "success_ap": 0.98,
        "success_ap_perturbed": (0.97, 0.04),
        "success_score_error": (-0.04, 0.16),
    },
    "scooping": {
        "n_objects": 5,
        "capture_ap": 0.96,
        "capture_ap_perturbed": (0.79, 0.03),
        "capture_score_error": (-0.00, 0.11),
        "success_ap": 1.00,
        "success_ap_perturbed": (0.98, 0.02),
        "success_score_error": (-0.01, 0.13),
    },
}
PAPER_FIG_2: dict[int, dict[str, Any]] = {
    3: {"runtime": (0.37, 0.13), "capture_ap": 0.99, "success_ap": 1.00},
    5: {"runtime": (0.66, 0.39), "capture_ap": 0.99, "success_ap": 0.99},
    7: {"runtime": (0.81, 0.39), "capture_ap": 0.99, "success_ap": 0.99},
    10: {"runtime": (1.20, 0.46), "capture_ap": 0.98, "success_ap": 1.00},
}

# Measured seconds per frame and per object at 300 iterations on the 2-core machine (docs/performance.md),
# used only to announce the expected duration.
_SECONDS_PER_OBJECT = {"pushing": 0.023, "scooping": 0.14}


@dataclass(frozen=True)
class ReproduceConfig:
    """What ``reproduce`` runs.

    Attributes:
        quick: the small variant (minutes on 2 cores) instead of the paper's sizes.
        trajectories: roll-outs per Table I dataset.
        frames: frames per roll-out.
        iterations: EST iterations per frame.
        repeats: perturbed copies per Table I dataset.
        ablation_objects: numbers of objects of the Fig. 2 ablation (pushing).
        ablation_trajectories: roll-outs per ablation dataset.
        ablation_frames: frames per ablation roll-out.
        workers: parallel workers.
        engine: physics engine.
        seed: seed of every dataset, perturbation and analysis.
    """

    quick: bool = False
    trajectories: int = 20
    frames: int = 10
    iterations: int = 300
    repeats: int = 5
    ablation_objects: tuple[int, ...] = (3, 5, 7, 10, 20)
    ablation_trajectories: int = 20
    ablation_frames: int = 10
    workers: int = 2
    engine: str = "mujoco"
    seed: int = 0

    @classmethod
    def create(cls, *, quick: bool, workers: int, engine: str, seed: int) -> ReproduceConfig:
        """The full or quick configuration."""
        if quick:
            return cls(
                quick=True,
                trajectories=6,
                frames=5,
                iterations=100,
                repeats=2,
                ablation_trajectories=3,
                ablation_frames=4,
                workers=workers,
                engine=engine,
                seed=seed,
            )
        return cls(workers=workers, engine=engine, seed=seed)

    def expected_seconds(self) -> float:
        """Rough duration on the reference 2-core machine, s."""
        scale = self.iterations / 300.0
        table = self.trajectories * self.frames * (1 + self.repeats)
        work = table * scale * (10 * _SECONDS_PER_OBJECT["pushing"] + 5 * _SECONDS_PER_OBJECT["scooping"])
        ablation_frames = self.ablation_trajectories * self.ablation_frames
        work += sum(ablation_frames * scale * n * _SECONDS_PER_OBJECT["pushing"] for n in self.ablation_objects)
        return work / max(1, min(self.workers, 2)) + 30.0


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _dataset(
    out: Path, name: str, task: str, n_objects: int, trajectories: int, frames: int, config: ReproduceConfig
) -> Path:
    from energy_margin.dataset import generate_dataset

    path = out / "data" / name
    generate_dataset(
        task,
        n_objects=n_objects,
        n_trajectories=trajectories,
        n_frames=frames,
        seed=config.seed,
        out=path,
        engine=config.engine,
    )
    return path


def _analyze(path: Path, config: ReproduceConfig) -> None:
    from energy_margin.analysis import AnalyzerConfig, analyze

    analyze(
        path,
        AnalyzerConfig(iterations=config.iterations, engine=config.engine),
        seed=config.seed,
        workers=config.workers,
        progress=sys.stderr.isatty(),
    )


def _table_one_row(
    out: Path, task: str, n_objects: int, config: ReproduceConfig, step: Callable[[str], None]
) -> dict[str, Any]:
    from energy_margin.perturb import perturb_dataset
    from energy_margin.robustness import compare_perturbed

    name = f"{task}-{n_objects}"
    step(f"generate {name}")
    path = _dataset(out, name, task, n_objects, config.trajectories, config.frames, config)
    step(f"analyze {name} (true states)")
    _analyze(path, config)
    step(f"perturb {name} ({config.repeats} copies)")
    copies = perturb_dataset(path, repeats=config.repeats, seed=config.seed, out=out / "data" / f"{name}-perturbed")
    for index, copy in enumerate(copies, start=1):
        step(f"analyze {name} perturbed copy {index}/{len(copies)}")
        _analyze(copy, config)
    result = compare_perturbed(path, [str(copy) for copy in copies])
    result["dataset"] = str(path.relative_to(out))
    return result


def _ablation_row(out: Path, n_objects: int, config: ReproduceConfig, step: Callable[[str], None]) -> dict[str, Any]:
    from energy_margin.evaluate import evaluate

    name = f"ablation-pushing-{n_objects}"
    step(f"generate {name}")
    path = _dataset(out, name, "pushing", n_objects, config.ablation_trajectories, config.ablation_frames, config)
    step(f"analyze {name}")
    _analyze(path, config)
    result = evaluate(path)
    return {
        "n_objects": n_objects,
        "dataset": str(path.relative_to(out)),
        "capture_ap": result["capture_ap"],
        "success_ap": result["success_ap"],
        "capture_ap_window2": result["capture_ap_window2"],
        "success_ap_first_half": result["success_ap_first_half"],
        "capture_positive_rate": result["capture_positive_rate"],
        "success_positive_rate": result["success_positive_rate"],
        "runtime_per_frame_s": result["runtime_per_frame_s"],
        "runtime_per_frame_std_s": result["runtime_per_frame_std_s"],
    }


def _number(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"


def _spread(entry: dict[str, Any] | None) -> str:
    if not entry or entry.get("mean") is None:
        return "n/a"
    return f"{entry['mean']:.2f} ± {entry['std']:.2f}"


def table_one_markdown(rows: dict[str, dict[str, Any]]) -> str:
    """Table I (ours beside the paper's) as Markdown."""
    lines = [
        "| task | n_o | | capture AP true | capture AP perturbed | capture score error "
        "| success AP true | success AP perturbed | success score error |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for task, row in rows.items():
        paper = PAPER_TABLE_I[task]
        lines.append(
            f"| {task} | {row['n_objects']} | this project | {_number(row['capture_ap'])} "
            f"| {_spread(row['capture_ap_perturbed'])} | {_spread(row['capture_score_error'])} "
            f"| {_number(row['success_ap'])} | {_spread(row['success_ap_perturbed'])} "
            f"| {_spread(row['success_score_error'])} |"
        )
        lines.append(
            f"| | {paper['n_objects']} | paper | {paper['capture_ap']:.2f} "
            f"| {paper['capture_ap_perturbed'][0]:.2f} ± {paper['capture_ap_perturbed'][1]:.2f} "
            f"| {paper['capture_score_error'][0]:.2f} ± {paper['capture_score_error'][1]:.2f} "
            f"| {paper['success_ap']:.2f} "
            f"| {paper['success_ap_perturbed'][0]:.2f} ± {paper['success_ap_perturbed'][1]:.2f} "
            f"| {paper['success_score_error'][0]:.2f} ± {paper['success_score_error'][1]:.2f} |"
        )
    return "\n".join(lines) + "\n"


def ablation_markdown(rows: list[dict[str, Any]]) -> str:
    """The Fig. 2 ablation (ours beside the paper's) as Markdown."""
    lines = [
        "| n_o | capture AP | success AP | runtime per frame [s] "
        "| paper capture AP | paper success AP | paper runtime [s] |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        paper = PAPER_FIG_2.get(row["n_objects"])
        paper_cells = "– | – | –"
        if paper:
            runtime = f"{paper['runtime'][0]:.2f} ± {paper['runtime'][1]:.2f}"
            paper_cells = f"{paper['capture_ap']:.2f} | {paper['success_ap']:.2f} | {runtime}"
        lines.append(
            f"| {row['n_objects']} | {_number(row['capture_ap'])} | {_number(row['success_ap'])} "
            f"| {row['runtime_per_frame_s']:.3f} ± {row['runtime_per_frame_std_s']:.3f} | {paper_cells} |"
        )
    return "\n".join(lines) + "\n"


def reproduce(out: Path | str, config: ReproduceConfig) -> Path:
    """Run every stage into ``out`` and return the path of the report's ``index.html``."""
    from energy_margin.report import write_report

    if config.workers < 1:
        raise EnergyMarginError(f"workers must be >= 1, got {config.workers}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    previous = out / "reproduce.json"
    resolved = dataclasses.asdict(config)
    if previous.is_file():
        try:
            stored = json.loads(previous.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError):
            stored = None
        if stored != json.loads(json.dumps(resolved)):
            raise EnergyMarginError(
                f"{out} holds a reproduction with other settings ({previous.name}); choose another --out"
            )
    write_json(previous, resolved)
    stages = 2 * (3 + config.repeats) + 2 * len(config.ablation_objects) + 1
    counter = {"done": 0}
    started = time.monotonic()

    def step(message: str) -> None:
        counter["done"] += 1
        elapsed = time.monotonic() - started
        _say(f"[{counter['done']}/{stages}] {message} ({elapsed:.0f} s elapsed)")

    minutes = config.expected_seconds() / 60.0
    _say(
        f"reproduce ({'quick' if config.quick else 'full'}): expected about {minutes:.0f} min with "
        f"{config.workers} worker(s) on a 2-core machine; interrupt at any time and run the same command to resume"
    )
    table_one = {
        task: _table_one_row(out, task, int(PAPER_TABLE_I[task]["n_objects"]), config, step)
        for task in ("pushing", "scooping")
    }
    ablation = [_ablation_row(out, n, config, step) for n in config.ablation_objects]
    write_json(out / "table1.json", _strip(table_one))
    atomic_write_text(out / "table1.md", table_one_markdown(table_one))
    write_json(out / "ablation.json", ablation)
    atomic_write_text(out / "ablation.md", ablation_markdown(ablation))
    step("report")
    index = write_report(out, table_one, ablation, config)
    _say(f"done in {time.monotonic() - started:.0f} s: {index}")
    return index


def _strip(rows: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    keys = (
        "n_objects",
        "dataset",
        "capture_ap",
        "success_ap",
        "capture_ap_perturbed",
        "success_ap_perturbed",
        "capture_score_error",
        "success_score_error",
        "capture_ap_window2",
        "success_ap_first_half",
        "capture_positive_rate",
        "success_positive_rate",
        "runtime_per_frame_s",
        "baselines",
    )
    return {task: {key: row.get(key) for key in keys} for task, row in rows.items()}
