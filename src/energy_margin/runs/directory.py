"""A run directory: the resolved settings written first, one rule for resuming, one writer at a time.

Every long command (``analyze``, ``perturb``, ``budget``, ``study``, ``sweep``, ``design``,
``control``, ``reproduce``) opens its output directory with :func:`open_run`:

1. The directory is created if needed and locked (:class:`~energy_margin.runs.lock.RunLock`): a
   second writer is refused in one line naming the first one's process and host.
2. If the run's settings file is there, the settings that decide the results are compared with
   the new ones. The same: the run resumes (``RunDirectory.resumed``). Different: refused in one
   line naming the first differing setting, unless ``overwrite``, which removes the run's own
   outputs (:attr:`RunSpec.outputs`, never another file) and starts afresh. Settings named in
   :attr:`RunSpec.may_differ` (a count that only grows the run, say) never make a run different.
3. A directory without the settings file must be empty, unless the run lives beside other files
   (:attr:`RunSpec.shared_directory`: the analysis of a dataset writes into the dataset's folder);
   ``overwrite`` removes the run's outputs there too, and nothing else.
4. The new settings are written (atomically) before any result, so a killed run resumes under them,
   with the engine and the versions of MuJoCo and numpy (:func:`~energy_margin.runs.versions.engine_versions`)
   under ``versions``: beside the settings, never compared. A run resumed under another engine
   version says so in one line on standard error, since its results may mix the two.

A writer killed during an atomic write leaves its temporary file (or staging folder) behind;
the next writer, holding the lock, removes those of the run's own files first (:func:`remove_stale`),
so they neither accumulate nor make a fresh directory look foreign.
"""

from __future__ import annotations

import json
import shutil
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from energy_margin._version import __version__
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.files import leftovers, read_json, remove_leftovers, write_json
from energy_margin.runs.lock import LOCK_FILE, RunLock
from energy_margin.runs.versions import VERSIONS_KEY, engine_difference, engine_versions, recorded_versions

__all__ = [
    "RunDirectory",
    "RunSpec",
    "difference",
    "open_run",
    "remove_outputs",
    "remove_stale",
    "run_directory",
    "run_versions",
]


@dataclass(frozen=True)
class RunSpec:
    """What a kind of run keeps in its directory and how it decides that a run is the same.

    Attributes:
        contents: what the directory holds, for messages ("scores", "episodes", "a sweep").
        settings_file: the file of resolved settings, written first ("analysis.json").
        outputs: files and folders the run writes besides the settings file; ``overwrite``
            removes exactly these.
        compared: the top-level settings that decide the results; ``None``: every one.
        may_differ: top-level settings that may change between runs without a different run.
        shared_directory: the directory may hold other files (a dataset's folder).
        settings_key: the settings sit under this key of the settings file (which then holds
            other things too, such as a summary); ``None``: the file is the settings.
        normalize: fills in settings of a file written by an earlier release before the
            comparison: ``normalize(settings, earlier)``, ``earlier`` for the stored ones.
        kept: top-level entries of a settings file that is the settings (``settings_key``
            ``None``) that a resumed run keeps as they were: what the run decided while running
            (``analyze``'s continuation choice), not settings.

    """

    contents: str
    settings_file: str
    outputs: tuple[str, ...] = ()
    compared: tuple[str, ...] | None = None
    may_differ: tuple[str, ...] = ()
    shared_directory: bool = False
    settings_key: str | None = None
    normalize: Callable[[dict[str, Any], bool], dict[str, Any]] | None = None
    kept: tuple[str, ...] = ()


@dataclass
class RunDirectory:
    """An open, locked run directory.

    Attributes:
        path: the directory.
        spec: the kind of run.
        settings: the run's resolved settings (as written).
        resumed: the directory held this very run (its outputs are kept).
        lock: the writer's lock, released by :meth:`close`.
        versions: what the settings file records under ``versions``: the package's version and
            :func:`~energy_margin.runs.versions.engine_versions` of the run's engine.

    """

    path: Path
    spec: RunSpec
    settings: dict[str, Any]
    resumed: bool
    lock: RunLock
    versions: dict[str, str] = field(default_factory=dict)

    @property
    def settings_path(self) -> Path:
        """The settings file."""
        return self.path / self.spec.settings_file

    def write_settings(self, extra: dict[str, Any] | None = None) -> None:
        """Rewrite the settings file (with ``extra`` beside the settings when they sit under a key)."""
        write_json(self.settings_path, _document(self.spec, self.settings, extra, self.versions))

    def close(self) -> None:
        """Release the lock (idempotent)."""
        self.lock.release()

    def __enter__(self) -> RunDirectory:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _document(
    spec: RunSpec, settings: dict[str, Any], extra: dict[str, Any] | None, versions: dict[str, str]
) -> dict[str, Any]:
    """The settings file's content: the settings, with the versions beside them (and ``extra``)."""
    record = {VERSIONS_KEY: versions} if versions else {}
    if spec.settings_key is None:
        kept = {key: (extra or {})[key] for key in spec.kept if key in (extra or {})}
        return {**settings, **kept, **record}
    return {**(extra or {}), **record, spec.settings_key: settings}


def run_versions(engine: str = "mujoco") -> dict[str, str]:
    """What a run's settings file records under ``versions``: the package's version and the engine's."""
    return {"energy_margin": __version__, **engine_versions(engine)}


def _plain(value: Any) -> Any:
    """``value`` as JSON would give it back (tuples as lists, keys as strings)."""
    return json.loads(json.dumps(value, sort_keys=True))


def difference(spec: RunSpec, previous: dict[str, Any], current: dict[str, Any]) -> str | None:
    """The first setting that makes ``current`` another run than ``previous`` ("key: A there, B now"), or ``None``."""
    if spec.normalize is not None:
        previous, current = spec.normalize(dict(previous), True), spec.normalize(dict(current), False)
    previous, current = _plain(previous), _plain(current)
    keys = spec.compared if spec.compared is not None else sorted(set(previous) | set(current))
    for key in keys:
        # The versions are recorded beside the settings, never compared: a run may resume under others.
        if key not in spec.may_differ and not (spec.compared is None and key == VERSIONS_KEY):
            found = _first_difference(key, previous.get(key), current.get(key))
            if found is not None:
                return found
    return None


def _first_difference(name: str, previous: Any, current: Any) -> str | None:
    """The first differing entry of two JSON values, as "name.sub: A there, B now"; ``None`` when equal."""
    if isinstance(previous, dict) and isinstance(current, dict):
        for key in sorted(set(previous) | set(current)):
            found = _first_difference(f"{name}.{key}", previous.get(key), current.get(key))
            if found is not None:
                return found
        return None
    if json.dumps(previous, sort_keys=True) != json.dumps(current, sort_keys=True):
        return f"{name}: {_short(previous)} there, {_short(current)} now"
    return None


def _short(value: Any, limit: int = 80) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _stored(spec: RunSpec, path: Path) -> tuple[dict[str, Any] | None, dict[str, Any]]:
    """The settings of the file at ``path`` (``None`` when it cannot be read as such) and what sits beside them."""
    try:
        document = read_json(path, what=f"{spec.contents} settings")
    except EnergyMarginError:
        return None, {}
    if not isinstance(document, dict):
        return None, {}
    if spec.settings_key is None:
        return document, {}
    settings = document.get(spec.settings_key)
    beside = {key: value for key, value in document.items() if key != spec.settings_key}
    return (settings if isinstance(settings, dict) else None), beside


def remove_outputs(path: Path, spec: RunSpec) -> None:
    """Remove the run's own files and folders from ``path`` (its settings file included)."""
    for name in (spec.settings_file, *spec.outputs):
        target = path / name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        else:
            target.unlink(missing_ok=True)


def remove_stale(path: Path, spec: RunSpec) -> list[Path]:
    """Remove what a killed writer of the run in ``path`` left half-written; the paths removed.

    Temporary files and staging folders of the settings file and of the outputs, and those
    inside output folders (the run's own). Only the lock's holder may call this.
    """
    found: list[Path] = []
    for name in (spec.settings_file, *spec.outputs):
        found += leftovers(path, name)
        target = path / name
        if target.is_dir() and not target.is_symlink():
            found += leftovers(target)
    remove_leftovers(found)
    return found


def _foreign(path: Path) -> list[str]:
    return sorted(entry.name for entry in path.iterdir() if entry.name != LOCK_FILE)


def open_run(
    path: Path | str, spec: RunSpec, settings: dict[str, Any], *, overwrite: bool = False, engine: str = "mujoco"
) -> RunDirectory:
    """Create or resume the run ``settings`` in ``path``, locked for this process.

    Args:
        path: the run directory (created with its parents when missing).
        spec: the kind of run.
        settings: the resolved settings (JSON-serialisable); a ``versions`` entry in them is
            replaced by the record of this run (:func:`run_versions`).
        overwrite: replace a run of other settings (or the run's files in a directory without
            its settings file) instead of refusing.
        engine: the physics engine of the run, recorded with the versions.

    Returns:
        The open directory; close it (or use it as a context manager) to release the lock.

    Raises:
        EnergyMarginError: ``path`` is a file, holds another run or other files, or is locked
            by a live process (:class:`~energy_margin.runs.lock.RunLockedError`).

    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise EnergyMarginError(f"{path} exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise EnergyMarginError(f"cannot create {path}: {error.strerror}") from None
    lock = RunLock(path).acquire()
    try:
        remove_stale(path, spec)
        resumed, beside = _check(path, spec, settings, overwrite=overwrite)
        versions = run_versions(engine)
        before = recorded_versions(beside)
        if resumed and before is not None:
            _say_other_versions(path, before, versions)
        plain = {key: value for key, value in _plain(settings).items() if key != VERSIONS_KEY}
        run = RunDirectory(path, spec, plain, resumed, lock, versions)
        # A resumed run keeps what sits beside its settings (a summary) while the settings update.
        run.write_settings(beside)
    except BaseException:
        lock.release()
        raise
    return run


def _say_other_versions(path: Path, before: dict[str, str], now: dict[str, str]) -> None:
    """One line on standard error when a run resumes under another engine version."""
    found = engine_difference(before, now)
    if found is not None:
        name, earlier, current = found
        print(
            f"note: {path} was started with {name} {earlier}; this is {name} {current}: "
            "results of the two versions can differ",
            file=sys.stderr,
            flush=True,
        )


def _check(path: Path, spec: RunSpec, settings: dict[str, Any], *, overwrite: bool) -> tuple[bool, dict[str, Any]]:
    """Whether ``path`` holds this very run (and what its settings file holds beside the settings).

    Beside the settings: the other entries of a file whose settings sit under a key, or the
    ``versions`` record of one whose settings are the file.

    Clears another run (``overwrite``) or refuses it.
    """
    settings_path = path / spec.settings_file
    if settings_path.exists():
        previous, beside = _stored(spec, settings_path)
        reason = "its settings file cannot be read" if previous is None else difference(spec, previous, settings)
        if reason is None:
            if spec.settings_key is None and previous is not None:
                recorded = {VERSIONS_KEY: previous[VERSIONS_KEY]} if VERSIONS_KEY in previous else {}
                beside = {**recorded, **{key: previous[key] for key in spec.kept if key in previous}}
            return True, beside
        if not overwrite:
            raise EnergyMarginError(
                f"{path} holds {spec.contents} of other settings ({reason}); "
                "pass `overwrite=True` to replace them or choose another `out`"
            )
        remove_outputs(path, spec)
        return False, {}
    if overwrite:
        remove_outputs(path, spec)
    foreign = _foreign(path)
    if foreign and not spec.shared_directory:
        raise EnergyMarginError(
            f"{path} already exists and is not a directory of {spec.contents} (no {spec.settings_file}; "
            f"it holds {', '.join(foreign[:3])}{', ...' if len(foreign) > 3 else ''}); choose another `out`"
        )
    return False, {}


@contextmanager
def run_directory(
    path: Path | str, spec: RunSpec, settings: dict[str, Any], *, overwrite: bool = False, engine: str = "mujoco"
) -> Iterator[RunDirectory]:
    """:func:`open_run` as a context manager that releases the lock at the end."""
    run = open_run(path, spec, settings, overwrite=overwrite, engine=engine)
    try:
        yield run
    finally:
        run.close()
