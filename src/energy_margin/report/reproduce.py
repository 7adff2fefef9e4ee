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
from pathlib import Path
from typing import Any

from energy_margin.data.io import atomic_write_text, write_json
from energy_margin.errors import EnergyMarginError
from energy_margin.report.config import ReproduceConfig
from energy_margin.report.html import write_report
from energy_margin.report.paper import PAPER_FIG_2, PAPER_TABLE_I


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _dataset(
    out: Path, name: str, task: str, n_objects: int, trajectories: int, frames: int, config: ReproduceConfig
) -> Path:
    from energy_margin.data.generate import generate_dataset

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
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import analyze

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
    from energy_margin.robustness.compare import compare_perturbed
    from energy_margin.robustness.perturb import perturb_dataset

    name = f"{task}-{n_objects}"
    step(f"generate {name}")
    path = _dataset(out, name, task, n_objects, config.trajectories, config.frames, config)
    step(f"analyze {name} (true states)")
    _analyze(path, config)
    step(f"perturb {name} ({config.repeats} copies)")
    copies = perturb_dataset(
        path,
        repeats=config.repeats,
        seed=config.seed,
        out=out / "data" / f"{name}-perturbed",
        workers=config.workers,
        progress=sys.stderr.isatty(),
    )
    for index, copy in enumerate(copies, start=1):
        step(f"analyze {name} perturbed copy {index}/{len(copies)}")
        _analyze(copy, config)
    result = compare_perturbed(path, [str(copy) for copy in copies])
    result["dataset"] = str(path.relative_to(out))
    return result


def _ablation_row(out: Path, n_objects: int, config: ReproduceConfig, step: Callable[[str], None]) -> dict[str, Any]:
    from energy_margin.evaluation.metrics import evaluate

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
