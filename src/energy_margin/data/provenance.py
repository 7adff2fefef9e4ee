"""Which engine versions made a dataset and its scores, and the one-line notes when they differ.

``dataset.json`` records :func:`~energy_margin.runs.versions.engine_versions` of the generation
under ``versions``; ``analysis.json`` records those of the analysis. Frames and scores depend on
the engine's version, so ``analyze``, ``evaluate`` and ``check`` say so when a dataset was
generated under another MuJoCo (or PyBullet) than the one installed (:func:`dataset_note`), and
``evaluate`` when the scores were computed under another version than the dataset's frames
(:func:`scores_note`). A note is a warning, never an error.

A dataset written before the record existed has unknown versions: it loads as before, no note is
printed, and ``check`` lists it (:func:`version_findings`). An imported set (``imported_from``)
holds the authors' frames, made by an engine this package did not run: it gets no note.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from energy_margin.data.dataset import FORMAT, METADATA_FILE, SCHEMA_VERSION, Problem
from energy_margin.data.scores_file import CONFIG_FILE, SCORES_FILE
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.files import read_json
from energy_margin.runs.versions import VERSIONS_KEY, engine_difference, engine_versions, recorded_versions

#: Why a note matters, the end of every note and finding.
CONSEQUENCE = "frames and scores can differ between engine versions"


def read_metadata(path: Path | str) -> dict[str, Any] | None:
    """``dataset.json`` of the dataset directory ``path`` when it is one this version reads, else ``None``.

    Never raises: a missing or unreadable file, or another format or schema version, gives
    ``None`` (the dataset's loader refuses those in its own words).
    """
    try:
        metadata = read_json(Path(path) / METADATA_FILE, what=METADATA_FILE)
    except (EnergyMarginError, OSError):
        return None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        return None
    return metadata if metadata.get("schema_version") == SCHEMA_VERSION else None


def _read_analysis(path: Path | str) -> dict[str, Any] | None:
    """``analysis.json`` of the dataset directory ``path``, ``None`` when absent or unreadable."""
    try:
        document = read_json(Path(path) / CONFIG_FILE, what=CONFIG_FILE)
    except (EnergyMarginError, OSError):
        return None
    return document if isinstance(document, dict) else None


def _generated(metadata: dict[str, Any]) -> dict[str, str] | None:
    """The versions that made the dataset's frames; ``None`` when unknown or not made here (imported)."""
    if metadata.get("imported_from"):
        return None
    return recorded_versions(metadata)


def _installed(metadata: dict[str, Any], engine: str | None) -> dict[str, str]:
    return engine_versions(engine if engine is not None else str(metadata.get("engine", "mujoco")))


def dataset_note(path: Path | str, *, engine: str | None = None, metadata: dict[str, Any] | None = None) -> str | None:
    """The one-line note for a dataset generated under another engine version than the installed one.

    Args:
        path: the dataset directory (named in the note).
        engine: the engine about to be used (``analyze --engine``); ``None``: the dataset's.
        metadata: its ``dataset.json``, read from ``path`` when ``None``.

    Returns:
        ``"note: runs/x was generated with MuJoCo 3.3.0; this is MuJoCo 4.0.0: frames and scores
        can differ between engine versions"``, or ``None`` (the same versions, unknown ones, an
        imported set, or a dataset this version does not read).
    """
    metadata = metadata if metadata is not None else read_metadata(path)
    generated = _generated(metadata) if metadata is not None else None
    if metadata is None or generated is None:
        return None
    found = engine_difference(generated, _installed(metadata, engine))
    if found is None:
        return None
    name, before, now = found
    return f"note: {path} was generated with {name} {before}; this is {name} {now}: {CONSEQUENCE}"


def scores_note(
    path: Path | str, *, metadata: dict[str, Any] | None = None, analysis: dict[str, Any] | None = None
) -> str | None:
    """The one-line note for scores computed under another engine version than the dataset's frames.

    Args:
        path: the dataset directory holding ``scores.csv`` and ``analysis.json``.
        metadata: its ``dataset.json``, read from ``path`` when ``None``.
        analysis: its ``analysis.json``, read from ``path`` when ``None``.

    Returns:
        ``"note: runs/x/scores.csv was computed with MuJoCo 4.0.1; runs/x was generated with MuJoCo
        4.0.0: frames and scores can differ between engine versions"``, or ``None`` (the same
        versions, either unknown, or an imported set).
    """
    metadata = metadata if metadata is not None else read_metadata(path)
    analysis = analysis if analysis is not None else _read_analysis(path)
    generated = _generated(metadata) if metadata is not None else None
    computed = recorded_versions(analysis)
    if generated is None or computed is None:
        return None
    found = engine_difference(generated, computed)
    if found is None:
        return None
    name, before, after = found
    return (
        f"note: {Path(path) / SCORES_FILE} was computed with {name} {after}; "
        f"{path} was generated with {name} {before}: {CONSEQUENCE}"
    )


def version_findings(path: Path | str, metadata: dict[str, Any]) -> list[Problem]:
    """What ``check`` lists of the versions of a dataset (and of its scores): warnings, not problems.

    Another engine version than the installed one, scores computed under another version than
    the frames, or no record at all (a dataset written before the record existed).
    """
    if metadata.get("imported_from"):
        return []
    generated = recorded_versions(metadata)
    if generated is None:
        what = "is not a valid record" if VERSIONS_KEY in metadata else "not recorded (an earlier release wrote it)"
        return [Problem(METADATA_FILE, VERSIONS_KEY, "", f"{what}: the engine versions of its frames are unknown")]
    findings = []
    found = engine_difference(generated, _installed(metadata, None))
    if found is not None:
        name, before, now = found
        message = f"generated with {name} {before}; this is {name} {now}: {CONSEQUENCE}"
        findings.append(Problem(METADATA_FILE, f"{VERSIONS_KEY}.{name.lower()}", "", message))
    computed = recorded_versions(_read_analysis(path))
    found = engine_difference(generated, computed) if computed is not None else None
    if found is not None and (Path(path) / SCORES_FILE).is_file():
        name, before, after = found
        message = f"scores computed with {name} {after}; the frames were generated with {name} {before}: {CONSEQUENCE}"
        findings.append(Problem(CONFIG_FILE, f"{VERSIONS_KEY}.{name.lower()}", "", message))
    return findings


__all__ = ["CONSEQUENCE", "dataset_note", "read_metadata", "scores_note", "version_findings"]
