"""``energy-margin reproduce``: the paper's Table I, the Fig. 2 ablation and a visual report.

Table I is reported under both perturbation protocols (docs/results/robustness.md): ``valid``
(physically valid copies, ``data/<task>-<n>-perturbed/R``) and ``paper`` (the authors' draw,
overlaps allowed, ``data/<task>-<n>-perturbed-paper/R``).

Every stage writes files and is skipped or resumed when run again: datasets are regenerated only
when missing, analyses resume from their journals, perturbed copies are kept. The resolved
configuration is saved as ``reproduce.json`` in the output directory.
"""

from __future__ import annotations

import dataclasses
import json
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from energy_margin._renamed import renamed_keys
from energy_margin.errors import check_int
from energy_margin.report.config import TABLE_ONE_PROTOCOLS, ReproduceConfig
from energy_margin.report.html import protocol_rows, write_report
from energy_margin.report.paper import PAPER_FIG_2, PAPER_TABLE_I
from energy_margin.runs import RunSpec, run_directory
from energy_margin.runs.files import atomic_write_text, write_json

__all__ = [
    "PROTOCOL_KEYS",
    "REPRODUCE_RUN",
    "ablation_markdown",
    "command_line",
    "reproduce",
    "table_one_markdown",
]


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
        AnalyzerConfig(expansions=config.expansions, engine=config.engine, continuation=0, capture_gate="none"),
        seed=config.seed,
        workers=config.workers,
        progress=sys.stderr.isatty(),
    )


#: What a Table I row holds per protocol (``by_protocol``).
PROTOCOL_KEYS = (
    "protocol",
    "capture_ap_perturbed",
    "success_ap_perturbed",
    "capture_score_error",
    "success_score_error",
    "runtime_per_frame_perturbed_s",
    "perturbed",
)


def _table_one_row(
    out: Path, task: str, n_objects: int, config: ReproduceConfig, step: Callable[[str], None]
) -> dict[str, Any]:
    """Table I for one task: the valid protocol's comparison, and ``by_protocol`` for both."""
    from energy_margin.robustness.compare import compare_perturbed
    from energy_margin.robustness.perturb import perturb_dataset

    name = f"{task}-{n_objects}"
    step(f"generate {name}")
    path = _dataset(out, name, task, n_objects, config.n_trajectories, config.n_frames, config)
    step(f"analyze {name} (true states)")
    _analyze(path, config)
    results = {}
    for protocol, suffix in TABLE_ONE_PROTOCOLS.items():
        step(f"perturb {name} ({config.repeats} copies, {protocol} protocol)")
        copies = perturb_dataset(
            path,
            repeats=config.repeats,
            seed=config.seed,
            out=out / "data" / f"{name}-{suffix}",
            protocol=protocol,
            workers=config.workers,
            progress=sys.stderr.isatty(),
        )
        for index, copy in enumerate(copies, start=1):
            step(f"analyze {name} perturbed copy {index}/{len(copies)} ({protocol} protocol)")
            _analyze(copy, config)
        result = compare_perturbed(path, [str(copy) for copy in copies]).to_dict()
        result["dataset"] = str(path.relative_to(out))
        result["perturbed"] = [str(Path(copy).relative_to(out)) for copy in copies]
        results[protocol] = result
    row = dict(results["valid"])
    row["by_protocol"] = {
        protocol: {key: result.get(key) for key in PROTOCOL_KEYS} for protocol, result in results.items()
    }
    return row


def _ablation_row(out: Path, n_objects: int, config: ReproduceConfig, step: Callable[[str], None]) -> dict[str, Any]:
    from energy_margin.evaluation.metrics import evaluate

    name = f"ablation-pushing-{n_objects}"
    step(f"generate {name}")
    path = _dataset(out, name, "pushing", n_objects, config.ablation_n_trajectories, config.ablation_n_frames, config)
    step(f"analyze {name}")
    _analyze(path, config)
    result = evaluate(path)
    return {
        "n_objects": n_objects,
        "dataset": str(path.relative_to(out)),
        "capture_ap": result.capture_ap,
        "success_ap": result.success_ap,
        "capture_ap_window2": result.capture_ap_window2,
        "success_ap_first_half": result.success_ap_first_half,
        "capture_positive_rate": result.capture_positive_rate,
        "success_positive_rate": result.success_positive_rate,
        "runtime_per_frame_s": result.runtime_per_frame_s,
        "runtime_per_frame_std_s": result.runtime_per_frame_std_s,
    }


def _number(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"


def _spread(entry: dict[str, Any] | None) -> str:
    if not entry or entry.get("mean") is None:
        return "n/a"
    return f"{entry['mean']:.2f} ± {entry['std']:.2f}"


def table_one_markdown(rows: dict[str, dict[str, Any]]) -> str:
    """Table I (ours under each perturbation protocol, beside the paper's) as Markdown."""
    lines = [
        "| task | n_o | | capture AP true | capture AP perturbed | capture score error "
        "| success AP true | success AP perturbed | success score error |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for task, row in rows.items():
        paper = PAPER_TABLE_I[task]
        for index, (label, perturbed) in enumerate(protocol_rows(row)):
            first = f"| {task} |" if index == 0 else "| |"
            lines.append(
                f"{first} {row['n_objects']} | {label} | {_number(row['capture_ap'])} "
                f"| {_spread(perturbed['capture_ap_perturbed'])} | {_spread(perturbed['capture_score_error'])} "
                f"| {_number(row['success_ap'])} | {_spread(perturbed['success_ap_perturbed'])} "
                f"| {_spread(perturbed['success_score_error'])} |"
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


def _announce(out: Path, config: ReproduceConfig) -> None:
    """Say how long the work left will take on this machine (a short calibration), or that none is left."""
    from energy_margin.report.estimate import estimate_seconds, measure_step_times, planned_analyses, work_left

    table_objects = {task: int(row["n_objects"]) for task, row in PAPER_TABLE_I.items()}
    plan = planned_analyses(config, table_objects)
    frames, to_write = work_left(out, plan)
    report_done = (out / "report" / "index.html").is_file()
    if not any(frames.values()) and not to_write:
        _say(
            f"reproduce ({'quick' if config.quick else 'full'}): every dataset is generated and analysed; "
            + ("writing the report again" if report_done else "writing the report")
        )
        return
    calibration = measure_step_times(config, list(table_objects))
    seconds = estimate_seconds(calibration, frames, to_write, workers=config.workers, report=True)
    left = sum(frames.values())
    rates = ", ".join(
        f"{task} {calibration.frame_s[task]:.2f} s/frame ({n} objects)" for task, n in table_objects.items()
    )
    resumed = "" if left == sum(e.n_trajectories * e.n_frames for e in plan) else f"{left} frames left; "
    _say(
        f"reproduce ({'quick' if config.quick else 'full'}): {resumed}expected about {_duration(seconds)} with "
        f"{config.workers} worker(s) on this machine (calibrated in {calibration.measured_s:.1f} s: {rates}); "
        "interrupt at any time and run the same command to resume"
    )


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60.0:.1f} min" if seconds < 600 else f"{seconds / 60.0:.0f} min"


def _record_stages(out: Path, stages: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Merge this run's stage times into ``stages.json``: a stage keeps its longest time.

    A resumed run skips finished work, so the longest time is the one that did the work.
    """
    path = out / "stages.json"
    previous: dict[str, Any] = {}
    if path.is_file():
        try:
            loaded = json.loads(path.read_text(encoding="utf-8"))
            previous = {entry["stage"]: entry for entry in loaded if isinstance(entry, dict) and "stage" in entry}
        except (OSError, ValueError, TypeError):
            previous = {}
    merged = []
    for entry in stages:
        earlier = previous.get(entry["stage"])
        if earlier is not None and float(earlier.get("seconds", 0.0)) > entry["seconds"]:
            merged.append({**earlier, "resumed": True})
        else:
            merged.append(entry)
    write_json(path, merged)
    return merged


def command_line(out: Path, config: ReproduceConfig) -> str:
    """The ``energy-margin reproduce`` command that runs ``config`` into ``out``."""
    quick = " --quick" if config.quick else ""
    return (
        f"energy-margin reproduce{quick} --out {shlex.quote(str(out))} --workers {config.workers} "
        f"--engine {config.engine} --seed {config.seed}"
    )


def reproduce(out: Path | str, config: ReproduceConfig, *, command: str | None = None, overwrite: bool = False) -> Path:
    """Run every stage into ``out`` and return the path of the report's ``index.html``.

    Args:
        out: output directory (locked while it runs; resumed when it holds this reproduction).
        config: what to run.
        command: the command line shown in the report's provenance (default: the equivalent
            ``energy-margin reproduce`` command).
        overwrite: replace a reproduction of other settings in ``out`` instead of refusing.

    """
    check_int("workers", config.workers, minimum=1)
    out = Path(out)
    with run_directory(out, REPRODUCE_RUN, dataclasses.asdict(config), overwrite=overwrite, engine=config.engine):
        return _reproduce(out, config, command=command)


#: A reproduction: ``reproduce.json`` (the resolved configuration), the datasets under ``data/``,
#: the tables and the report. The number of workers does not change a result.
REPRODUCE_RUN = RunSpec(
    contents="a reproduction",
    settings_file="reproduce.json",
    outputs=("data", "report", "table1.json", "table1.md", "ablation.json", "ablation.md", "stages.json"),
    may_differ=("workers",),
    normalize=lambda settings, earlier: renamed_keys(settings),
)


def _reproduce(out: Path, config: ReproduceConfig, *, command: str | None) -> Path:
    from energy_margin.report.provenance import provenance

    stages = 2 * (2 + len(TABLE_ONE_PROTOCOLS) * (1 + config.repeats)) + 2 * len(config.ablation_objects) + 1
    started = time.monotonic()
    timings: list[dict[str, Any]] = []

    def close_stage() -> None:
        if timings and "seconds" not in timings[-1]:
            timings[-1]["seconds"] = time.monotonic() - timings[-1].pop("_started")
            timings[-1]["resumed"] = False

    def step(message: str) -> None:
        close_stage()
        timings.append({"stage": message, "_started": time.monotonic()})
        elapsed = time.monotonic() - started
        _say(f"[{len(timings)}/{stages}] {message} ({elapsed:.0f} s elapsed)")

    _announce(out, config)
    table_one = {
        task: _table_one_row(out, task, int(row["n_objects"]), config, step) for task, row in PAPER_TABLE_I.items()
    }
    ablation = [_ablation_row(out, n, config, step) for n in config.ablation_objects]
    write_json(out / "table1.json", _strip(table_one))
    atomic_write_text(out / "table1.md", table_one_markdown(table_one))
    write_json(out / "ablation.json", ablation)
    atomic_write_text(out / "ablation.md", ablation_markdown(ablation))
    step("report")

    def describe() -> dict[str, Any]:
        # Called when the page is assembled: the report stage has drawn every figure by then.
        close_stage()
        recorded = _record_stages(out, timings)
        return provenance(
            engine=config.engine,
            command=command or command_line(out, config),
            stages=recorded,
            total_s=time.monotonic() - started,
        )

    index = write_report(out, table_one, ablation, config, describe=describe)
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
        "perturbed",
        "protocol",
        "by_protocol",
    )
    return {task: {key: row.get(key) for key in keys} for task, row in rows.items()}
