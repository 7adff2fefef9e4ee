"""Perturbed states: the perception-noise experiment of the paper's Section III.C (Table I).

For every frame of a dataset, the object centres are replaced by points drawn uniformly inside
the minimum-volume ellipsoid of the true centres (:func:`~energy_margin.world.ellipsoid.min_volume_ellipsoid`)
- as if perception only delivered the group's ellipsoid - and the objects are set at rest.

* Coordinates: planar tasks (upright objects, e.g. pushing) fit the 2-D ellipse of the (x, y)
  centres and put every object at its resting height on the ground (the recorded heights sink
  into the soft ground by up to ~2 mm); free objects (e.g. scooping) fit the 3-D ellipsoid.
* Orientation: set to the identity (pushing: yaw 0; scooping: boxes flat and axis-aligned), as
  the authors do - perception that only sees the ellipsoid does not know the objects' poses.
  ``keep_orientation=True`` keeps each object's recorded orientation instead.
* Velocities: zero (linear and angular). The end-effector, friction, drive and labels are not
  perturbed: the ground truth stays that of the true states; only the perceived state changes.
* Stable draws: candidates are drawn from the fitted ellipsoid snapped to a 1e-7 grid
  (:meth:`~energy_margin.world.ellipsoid.Ellipsoid.snapped`), so fits that differ by rounding give
  identical copies (tested with the fit's parameters scaled by 1 + 1e-12).
* Two protocols (``protocol``). ``"valid"`` (the default) gives physically valid states: no
  overlaps, as below. ``"paper"`` is the authors' draw exactly: one point per object drawn at once
  inside the fitted ellipsoid, nothing checked, so objects may interpenetrate each other, the
  end-effector and the ground or table; no restarts, no growth.
* No overlaps (``"valid"``, unlike the authors' version): objects are placed one at a time by **rejection**.
  A candidate is accepted when, in the task's simulator (the frame's scene, with the objects not
  yet placed parked far away), no contact of the new object - with another object, the
  end-effector, the table, ground or wall - penetrates deeper than ``tolerance``. Rejection keeps
  the draw uniform over the admissible part of the ellipsoid. After ``max_attempts`` rejected
  candidates for one object the frame starts over; after ``max_restarts`` restarts the sampling
  ellipsoid's radii grow by 10 % per further restart (the fallback; counted in ``dataset.json``).
  A frame that still cannot be placed is an error.
* Seeds: repeat r, frame i (trajectory-major) uses
  ``SeedSequence(seed).spawn(repeats)[r].spawn(T * K)[i]``: deterministic, per-frame independent.

Layout: ``out/1`` ... ``out/R``, each a dataset directory like any other (format 1), whose
``dataset.json`` gains a ``perturbation`` object (source, repeat, seed, settings, counts).
"""

from __future__ import annotations

import dataclasses
import functools
import signal
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.executors import pool_results
from energy_margin.data.dataset import Dataset, load_dataset, validate
from energy_margin.data.dataset_files import check_target as _check_target
from energy_margin.data.dataset_files import write_directory as _write_directory
from energy_margin.errors import (
    EnergyMarginError,
    InvalidParameterError,
    check_choice,
    check_float,
    check_int,
    check_seed,
)
from energy_margin.robustness.resample import (
    OVERLAP_DEPTH,
    PROTOCOL_METHODS,
    PROTOCOLS,
    FramePerturbation,
    is_planar,
    object_size,
    perturb_frame,
)
from energy_margin.runs import RunSpec, progress_bar, run_directory
from energy_margin.runs.progress import Progress
from energy_margin.runs.versions import VERSIONS_KEY, engine_versions

__all__ = [
    "PERTURB_RUN",
    "perturb_dataset",
]


def perturb_dataset(
    path: Path | str,
    *,
    repeats: int,
    seed: int,
    out: Path | str,
    tolerance: float | None = None,
    keep_orientation: bool = False,
    protocol: str = "valid",
    min_thickness: float | None = None,
    overwrite: bool = False,
    workers: int = 1,
    progress: Progress = False,
) -> list[Path]:
    """Write ``repeats`` perturbed copies of the dataset at ``path`` as ``out/1`` ... ``out/R``.

    Args:
        path: the true-state dataset.
        repeats: number of perturbed copies R, >= 1.
        seed: non-negative integer seed.
        out: parent directory of the copies.
        tolerance: largest accepted contact penetration of a resampled object, m, >= 0 (default
            5e-4; ``protocol="valid"`` only).
        keep_orientation: keep recorded orientations (default: identity, as the authors).
        protocol: ``"valid"`` (no overlaps, the default) or ``"paper"`` (the authors' draw,
            overlaps allowed); recorded as ``perturbation.protocol`` in ``dataset.json``.
        min_thickness: radius of flat ellipsoid axes, m; default the object radius (pushing) or
            half edge (scooping).
        overwrite: replace existing copies.
        workers: processes that perturb trajectories in parallel, >= 1 (the copies do not
            depend on it: every frame has its own seed).
        progress: show a progress bar over the frames on standard error.

    Returns:
        The paths of the copies. A copy already written with the same settings is kept as is.

    """
    tolerance = _checked_options(repeats, seed, workers, protocol, tolerance, min_thickness)
    source = load_dataset(path)
    out = _checked_out(path, out)
    thickness = float(min_thickness) if min_thickness is not None else object_size(source)
    planar = is_planar(source)
    settings = _copy_settings(protocol, planar=planar, thickness=thickness, keep_orientation=keep_orientation)
    if protocol == "valid":
        settings.update(tolerance_m=float(tolerance))
    run_settings = {"source": str(Path(path)), "seed": int(seed), "repeats": int(repeats), **settings}
    targets = [out / str(r + 1) for r in range(repeats)]
    spec = dataclasses.replace(PERTURB_RUN, outputs=tuple(target.name for target in targets))
    with run_directory(out, spec, run_settings, overwrite=overwrite):
        pending = _pending(targets, source, seed, settings, overwrite=overwrite)
        if pending:
            options = {
                "planar": planar,
                "min_thickness": thickness,
                "tolerance": tolerance,
                "keep_orientation": keep_orientation,
                "protocol": protocol,
            }
            copy = functools.partial(
                _write_copy, source, path, settings, seed=seed, repeats=repeats, overwrite=overwrite
            )
            _perturb_copies(
                source, options, targets, pending, seed=seed, workers=workers, progress=progress, write=copy
            )
    return targets


def _checked_options(
    repeats: int, seed: int, workers: int, protocol: str, tolerance: float | None, min_thickness: float | None
) -> float:
    """The penetration tolerance (m, 5e-4 by default) once every option is checked."""
    check_int("repeats", repeats, minimum=1)
    check_seed(seed)
    check_int("workers", workers, minimum=1)
    check_choice("protocol", protocol, PROTOCOLS)
    if tolerance is not None and protocol != "valid":
        raise EnergyMarginError(
            f"tolerance applies to the valid protocol only (protocol {protocol!r} checks no overlaps)"
        )
    tolerance = check_float("tolerance", 5e-4 if tolerance is None else tolerance, minimum=0.0)
    if min_thickness is not None:
        check_float("min_thickness", min_thickness, minimum=0.0, exclusive_minimum=True)
    return tolerance


def _checked_out(path: Path | str, out: Path | str) -> Path:
    """The copies' parent directory: neither the dataset nor inside it, and not a file."""
    out = Path(out)
    if out.resolve() == Path(path).resolve() or Path(path).resolve() in out.resolve().parents:
        raise InvalidParameterError("out", f"{out} must not be the dataset {path} or lie inside it")
    if out.exists() and not out.is_dir():
        raise EnergyMarginError(f"{out} exists and is not a directory")
    return out


def _pending(
    targets: list[Path], source: Dataset, seed: int, settings: dict[str, Any], *, overwrite: bool
) -> list[Path]:
    """The copies still to write (a copy with the same settings is kept); refuses others unless ``overwrite``."""
    pending = []
    for target in targets:
        if not _existing(target, source, seed, settings):
            _check_target(target, overwrite=overwrite)
            pending.append(target)
    return pending


#: A directory of perturbed copies: ``perturb.json`` (the settings) and the copies ``1`` ... ``R``.
#: The number of copies may grow: copy r's draws do not depend on it. Copies of an earlier release
#: (without ``perturb.json``) are checked one by one, so the directory may hold them.
PERTURB_RUN = RunSpec(
    contents="perturbed copies", settings_file="perturb.json", may_differ=("repeats",), shared_directory=True
)


def _copy_settings(protocol: str, *, planar: bool, thickness: float, keep_orientation: bool) -> dict[str, Any]:
    """The perturbation settings every copy records (``perturbation`` in its ``dataset.json``)."""
    settings: dict[str, Any] = {
        "protocol": protocol,
        "method": PROTOCOL_METHODS[protocol],
        "coordinates": "xy" if planar else "xyz",
        "min_thickness_m": thickness,
        "keep_orientation": bool(keep_orientation),
        "velocities": "zero",
    }
    if protocol == "valid":
        settings.update(max_attempts=500, max_restarts=3, growth_per_restart=1.1)
    return settings


def _perturb_copies(
    source: Dataset,
    options: dict[str, Any],
    targets: list[Path],
    pending: list[Path],
    *,
    seed: int,
    workers: int,
    progress: Progress,
    write: Callable[[int, Path, dict[int, list[FramePerturbation]]], None],
) -> None:
    """Perturb the copies ``pending`` (trajectories on workers); each is written as soon as it is complete."""
    total = source.n_trajectories * source.n_frames
    repeat_seeds = np.random.SeedSequence(seed).spawn(len(targets))
    jobs = [
        (r, trajectory, repeat_seeds[r].spawn(total)[trajectory * source.n_frames : (trajectory + 1) * source.n_frames])
        for r, target in enumerate(targets)
        if target in pending
        for trajectory in range(source.n_trajectories)
    ]
    results: dict[int, dict[int, list[FramePerturbation]]] = {}
    bar = progress_bar(len(jobs) * source.n_frames, desc="perturb", enabled=progress)
    try:
        for (r, trajectory), frames in _run_jobs(source, options, jobs, workers):
            results.setdefault(r, {})[trajectory] = frames
            bar.update(len(frames))
            if len(results[r]) == source.n_trajectories:
                write(r, targets[r], results.pop(r))
    finally:
        bar.close()


def _write_copy(
    source: Dataset,
    path: Path | str,
    settings: dict[str, Any],
    r: int,
    target: Path,
    results: dict[int, list[FramePerturbation]],
    *,
    seed: int,
    repeats: int,
    overwrite: bool,
) -> None:
    """Write copy ``r`` (``target``) from its trajectories' perturbed frames, with its counts."""
    arrays = {key: value.copy() for key, value in source.arrays.items()}
    candidates = restarts = grown = overlapping = 0
    growths, depths = [], []
    for trajectory in range(source.n_trajectories):
        for index, result in enumerate(results[trajectory]):
            arrays["object_pos"][trajectory, index] = result.frame.object_pos
            arrays["object_quat"][trajectory, index] = result.frame.object_quat
            arrays["object_vel"][trajectory, index] = 0.0
            candidates += result.candidates
            restarts += result.restarts
            grown += result.growth > 1.0
            growths.append(result.growth)
            overlapping += result.penetration > OVERLAP_DEPTH
            depths.append(result.penetration)
    metadata = dict(source.metadata)
    metadata["perturbation"] = {
        **settings,
        "source": str(Path(path)),
        "source_seed": source.metadata.get("seed"),
        "repeat": r + 1,
        "repeats": repeats,
        "seed": int(seed),
        "candidates": int(candidates),
        "restarts": int(restarts),
        "frames_with_grown_ellipsoid": int(grown),
        "largest_growth": float(max(growths)),
        "frames_with_overlaps": int(overlapping),
        "deepest_penetration_m": float(max(depths)),
        # The frames keep the source's record (``versions``); this is the software that moved them.
        VERSIONS_KEY: engine_versions(),
    }
    dataset = Dataset(path=target, metadata=metadata, arrays=arrays)
    validate(dataset)
    _write_directory(target, metadata, arrays, overwrite=overwrite)


_Job = tuple[int, int, list[np.random.SeedSequence]]
_WORKER_STATE: dict[str, Any] = {}


def _perturb_trajectory(source: Dataset, options: dict[str, Any], job: _Job) -> list[FramePerturbation]:
    """Perturb every frame of one trajectory for one repeat (the job's per-frame seeds)."""
    _, trajectory, seeds = job
    friction = float(source.arrays["friction"][trajectory])
    drive = source.arrays["drive"][trajectory]
    simulator = source.task.make_simulator(source.n_objects, friction, drive, source.metadata["engine"])
    return [
        perturb_frame(source.frame(trajectory, index), simulator, np.random.default_rng(child), **options)
        for index, child in enumerate(seeds)
    ]


def _init_worker(source: Dataset, options: dict[str, Any]) -> None:
    # Ctrl-C goes to the parent, which stops the pool.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER_STATE.update(source=source, options=options)


def _run_in_worker(job: _Job) -> tuple[tuple[int, int], list[FramePerturbation]]:
    return (job[0], job[1]), _perturb_trajectory(_WORKER_STATE["source"], _WORKER_STATE["options"], job)


def _run_jobs(
    source: Dataset, options: dict[str, Any], jobs: list[_Job], workers: int
) -> Iterator[tuple[tuple[int, int], list[FramePerturbation]]]:
    """Results of every job, in completion order, in this process or on ``workers`` processes."""
    if workers == 1 or len(jobs) <= 1:
        for job in jobs:
            yield (job[0], job[1]), _perturb_trajectory(source, options, job)
        return
    yield from pool_results(_run_in_worker, jobs, workers=workers, initializer=_init_worker, initargs=(source, options))


def _existing(target: Path, source: Dataset, seed: int, settings: dict[str, Any]) -> bool:
    """Whether ``target`` already holds the copy these settings would write."""
    if not (target / "dataset.json").is_file():
        return False
    try:
        existing = load_dataset(target)
    except EnergyMarginError:
        return False
    info = existing.metadata.get("perturbation")
    if not isinstance(info, dict) or info.get("seed") != int(seed):
        return False
    # Copies written before there was a choice of protocol are valid-protocol copies.
    info = {"protocol": "valid", **info}
    if any(info.get(key) != value for key, value in settings.items()):
        return False
    same_shape = all(
        existing.metadata.get(k) == source.metadata.get(k) for k in ("task", "n_trajectories", "n_frames", "n_objects")
    )
    return same_shape and bool(np.array_equal(existing.arrays["captured"], source.arrays["captured"]))
