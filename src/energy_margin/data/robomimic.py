"""robomimic / robosuite demonstration files (HDF5) turned into a dataset (``record --format robomimic``).

The layout: a group ``data`` with one subgroup per demonstration, ``data/demo_0``, ``data/demo_1``,
... (taken in the order of the integer after ``demo_``). Each holds the dataset ``states`` (N, D),
the flattened MuJoCo state of every step (robosuite's ``MjSimState.flatten()``: time, qpos, qvel,
so D = 1 + nq + nv; D = nq + nv without the time is read too, the time of row i then being
i * dt), optionally ``actions`` (N, A), and the attribute ``model_file``, the MuJoCo model's XML.
``data`` may carry ``total`` and ``env_args`` (JSON; ``env_kwargs.control_freq`` gives dt = 1 /
control_freq for states without the time).

Each demonstration's model is rebuilt from its XML with ``mujoco.MjSpec``. The asset files a
robosuite XML names by the absolute paths of the machine that recorded it are looked for again:
a path that does not exist is re-rooted under the ``assets`` folder given (the part after
``models/assets/``, else the file's name) or under the installed robosuite's ``models/assets``
folder (found without importing robosuite). Every demonstration must compile to the same model.

The objects and the capture and success sets come from a scene file (its ``objects``,
``perturbation``, ``bounds``, ``capture`` and ``success`` tables; its model is not loaded) or from
body patterns and region tables given directly. The dataset directory gets a scene of its own,
``source/model.xml`` (the re-rooted XML) and ``source/scene.toml``, which its ``dataset.json``
names, so every later command rebuilds the task from the directory. Its motion declares
``robot = "still"``: the states carry no actuator commands, so during analysis the robot is held
where each frame has it. Frames and labels are made as
:func:`~energy_margin.data.record.record_dataset` makes them. Every problem is one line naming the
file and the demonstration; nothing is written then.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import re
import shutil
import tomllib
import xml.etree.ElementTree as ElementTree
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.data.dataset import Dataset, check_target, write_directory
from energy_margin.data.generate import records_dataset
from energy_margin.data.record import DROPPED_KEY, check_rollout, rollout_records
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_positive_float, check_positive_int
from energy_margin.runs.files import staging_directory
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_file import (
    SCHEMA_VERSION,
    SceneSpec,
    scene_spec_from_tables,
    set_table,
    toml_key,
    toml_value,
)
from energy_margin.tasks.scene_model import LoadedScene, model_hash, resolve_scene
from energy_margin.tasks.scene_task import SceneTask

#: The folder of the dataset directory that holds its own scene file and model.
SOURCE_FOLDER = "source"
#: The scene file written into :data:`SOURCE_FOLDER`.
SCENE_FILE = "scene.toml"
#: The model written into :data:`SOURCE_FOLDER`.
MODEL_FILE = "model.xml"
#: A demonstration's states carry no actuator commands (robomimic's actions are a controller's
#: inputs), so during analysis the robot is held where each frame has it (``motion.robot``).
ROBOT_DURING_ANALYSIS = "still"

#: Elements of a model whose ``file`` attributes name asset files, and the compiler folder each reads.
_ASSET_ELEMENTS = {"mesh": "meshdir", "skin": "meshdir", "hfield": "assetdir", "texture": "texturedir"}
#: The six face files of a cube texture.
_TEXTURE_FACES = ("fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")
_ROBOSUITE_ASSETS = "robosuite/models/assets/"
_MODELS_ASSETS = "models/assets/"
_DEMO = re.compile(r"demo_(\d+)")
#: What h5py raises for a file, group, dataset or attribute it cannot read.
_HDF5_ERRORS = (OSError, RuntimeError, ValueError, KeyError, TypeError)
#: The scene-file tables a robomimic recording takes from a scene file.
_SCENE_TABLES = ("schema_version", "objects", "perturbation", "bounds", "capture", "success")


@dataclass(frozen=True)
class _RawDemo:
    """One demonstration as stored: its key, ``states`` (N, D), ``model_file`` text, ``actions`` rows."""

    key: str
    states: np.ndarray
    model_file: str
    action_rows: int | None


@dataclass(frozen=True)
class _BuiltModel:
    """A demonstration's model: the re-rooted XML, the compiled model and its SHA-256."""

    xml: str
    model: mujoco.MjModel
    sha256: str


def record_robomimic(
    path: Path | str,
    *,
    n_frames: int,
    out: Path | str,
    scene_file: Path | str | None = None,
    objects: str | Sequence[str] | None = None,
    capture: Mapping[str, Any] | str | None = None,
    success: Mapping[str, Any] | str | None = None,
    assets: Path | str | None = None,
    dt: float | None = None,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
    drop_unphysical: bool = False,
) -> Dataset:
    """Turn the demonstrations of a robomimic / robosuite HDF5 file into a dataset directory.

    Args:
        path: the HDF5 file (``data/demo_*`` with ``states`` and the attribute ``model_file``).
        n_frames: frames K per demonstration, >= 1 (at most the rows of the shortest one).
        out: the dataset directory to create.
        scene_file: a scene file whose ``objects``, ``perturbation``, ``bounds``, ``capture`` and
            ``success`` tables apply (its ``mjcf`` is not loaded: the demonstrations' model is the
            model); instead of ``objects``, ``capture`` and ``success``.
        objects: object body names or glob patterns, a list or one comma-separated string.
        capture: the capture set: a region table (``{"type": "box", ...}``) or a scene file's
            ``[capture]`` table (``{"region": {...}, "at_least": 2}``), as a mapping or JSON text.
        success: the success set, likewise.
        assets: a folder to look for asset files (meshes, textures) the XML names by paths that do
            not exist here: the part of such a path after ``models/assets/``, else its file name.
        dt: seconds between rows for states without the time column (default: 1 /
            ``env_kwargs.control_freq`` of the file's ``env_args``).
        overwrite: replace an existing ``out``.
        drop_unphysical: leave out the demonstrations with a physically impossible frame (listed
            under ``dropped`` in ``dataset.json``) instead of refusing them.
        progress: called with 1 after each demonstration.

    Returns:
        The dataset written to ``out``, whose ``source/scene.toml`` and ``source/model.xml`` rebuild its task.

    Raises:
        EnergyMarginError: a file that is not in this layout, a demonstration whose states do not
            fit its model, hold a NaN or are too short, a model that does not compile or compiles
            to another model than the first demonstration's, an asset file that cannot be found,
            or a bad scene file or region table; one line each, and nothing is written.
    """
    check_positive_int("n_frames", n_frames)
    if dt is not None:
        check_positive_float("dt", dt)
    path = Path(path)
    out = Path(out)
    tables = _set_tables(scene_file, objects, capture, success)
    assets_folder = _assets_folder(assets)
    check_target(out, overwrite=overwrite)
    raw_demos, env_dt = _read_file(path)
    built = _build_models(path, raw_demos, assets_folder)
    model = built[0].model
    rollouts = [_rollout(path, demo, model, dt if dt is not None else env_dt, n_frames) for demo in raw_demos]
    duration = max(float(arrays["time"][-1]) for _, arrays in rollouts)
    if duration <= 0:
        duration = float(model.opt.timestep)
    spec = _scene_spec(tables, scene_file, path, duration)
    loaded = resolve_scene(spec, model)
    scene_text = _scene_text(spec, loaded, duration)
    sources = [
        {
            "file": path.name,
            "sha256": _file_sha256(path),
            "format": "robomimic",
            "demos": [demo.key for demo in raw_demos],
        }
    ]
    return _write(
        out,
        built[0],
        scene_text,
        rollouts,
        n_frames,
        sources,
        overwrite=overwrite,
        progress=progress,
        drop_unphysical=drop_unphysical,
    )


# -- arguments ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Tables:
    """Where the objects and sets come from: a scene file's document, or the tables given."""

    document: dict[str, Any]
    from_scene: bool


def _set_tables(
    scene_file: Path | str | None,
    objects: str | Sequence[str] | None,
    capture: Mapping[str, Any] | str | None,
    success: Mapping[str, Any] | str | None,
) -> _Tables:
    """The scene tables of the objects and sets, from ``scene_file`` or from the other three."""
    if scene_file is not None:
        for name, value in (("objects", objects), ("capture", capture), ("success", success)):
            if value is not None:
                raise InvalidParameterError(name, "cannot be combined with a scene file, which gives it")
        return _Tables(_scene_document(Path(scene_file)), from_scene=True)
    for name, value in (("objects", objects), ("capture", capture), ("success", success)):
        if value is None:
            raise InvalidParameterError(
                name, "is needed without a scene file: give a scene file, or the objects, capture and success sets"
            )
    assert objects is not None and capture is not None and success is not None
    patterns = [part.strip() for part in objects.split(",")] if isinstance(objects, str) else list(objects)
    if not patterns or any(not isinstance(p, str) or not p.strip() for p in patterns):
        raise InvalidParameterError("objects", f"must be body names or patterns separated by commas, got {objects!r}")
    document = {
        "objects": {"bodies": [p.strip() for p in patterns]},
        "capture": _set_table("capture", capture),
        "success": _set_table("success", success),
    }
    return _Tables(document, from_scene=False)


def _set_table(name: str, value: Mapping[str, Any] | str) -> dict[str, Any]:
    """A set's table ``{"region": ..., "at_least": ...}`` from a region table or the set's table (JSON or mapping)."""
    if isinstance(value, str):
        try:
            value = json.loads(value)
        except (ValueError, RecursionError) as error:
            raise InvalidParameterError(name, f"is not valid JSON ({error})") from None
    return set_table(name, value)


def _scene_document(path: Path) -> dict[str, Any]:
    """The tables of the scene file at ``path`` that apply to a recording (see :data:`_SCENE_TABLES`)."""
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise EnergyMarginError(f"{path}: scene file does not exist") from None
    except OSError as error:
        raise EnergyMarginError(f"{path}: cannot read the scene file ({error.strerror})") from None
    except UnicodeDecodeError:
        raise EnergyMarginError(f"{path}: the scene file is not UTF-8 text") from None
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise EnergyMarginError(f"{path}: not valid TOML ({error})") from None
    except RecursionError:
        raise EnergyMarginError(f"{path}: not valid TOML (arrays or tables nested too deeply)") from None
    objects = document.get("objects")
    if isinstance(objects, dict) and "template" in objects:
        raise EnergyMarginError(
            f"{path}: objects.template: a recorded model is used as it is: name its object bodies in objects.bodies"
        )
    return {key: document[key] for key in _SCENE_TABLES if key in document}


def _assets_folder(assets: Path | str | None) -> Path | None:
    if assets is None:
        return None
    folder = Path(assets)
    if not folder.is_dir():
        raise InvalidParameterError("assets", f"must be a folder, got {str(folder)!r}")
    return folder.resolve()


# -- the file ----------------------------------------------------------------------------------


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def _text(value: Any) -> str | None:
    """An HDF5 string attribute as text (h5py gives ``str``, ``bytes`` or a NumPy scalar)."""
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, bytes | np.bytes_):
        try:
            return bytes(value).decode("utf-8")
        except UnicodeDecodeError:
            return None
    if isinstance(value, str):
        return value
    return None


def _read_file(path: Path) -> tuple[list[_RawDemo], float | None]:
    """The demonstrations of the file at ``path`` in the order of their numbers, and ``env_args``' dt."""
    try:
        import h5py
    except ImportError:
        raise EnergyMarginError(
            f"{path}: reading robomimic files needs h5py: pip install 'energy-margin[demos]'"
        ) from None
    try:
        is_file = path.is_file()
    except OSError as error:
        raise EnergyMarginError(f"{path}: cannot be read ({error.strerror})") from None
    if not is_file:
        raise EnergyMarginError(f"{path}: {'is not a file' if path.exists() else 'does not exist'}")
    demos: list[_RawDemo] = []
    try:
        with h5py.File(path, "r") as handle:
            data = handle.get("data")
            if not isinstance(data, h5py.Group):
                raise EnergyMarginError(
                    f"{path}: has no group 'data' (a robomimic file holds data/demo_0, data/demo_1, ...)"
                )
            numbered = sorted((int(match.group(1)), name) for name in data if (match := _DEMO.fullmatch(name)))
            if not numbered:
                raise EnergyMarginError(f"{path}:/data: holds no demonstration (groups demo_0, demo_1, ...)")
            env_dt = _env_dt(data.attrs.get("env_args"))
            for _, key in numbered:
                demos.append(_read_demo(h5py, path, key, data[key]))
    except EnergyMarginError:
        raise
    except _HDF5_ERRORS as error:
        raise EnergyMarginError(f"{path}: not a readable HDF5 file ({_one_line(error)})") from None
    return demos, env_dt


def _read_demo(h5py: Any, path: Path, key: str, group: Any) -> _RawDemo:
    where = f"{path}:/data/{key}"
    if not isinstance(group, h5py.Group):
        raise EnergyMarginError(f"{where}: is a dataset, expected a group with states and model_file")
    states_item = group.get("states")
    if not isinstance(states_item, h5py.Dataset):
        raise EnergyMarginError(f"{where}: has no dataset 'states' (N, 1 + nq + nv), the flattened MuJoCo state")
    if states_item.shape is None or states_item.dtype.kind not in "fiu":
        raise EnergyMarginError(f"{where}: states: must hold numbers, got {states_item.dtype}")
    states = np.asarray(states_item[()], dtype=float)
    if states.ndim != 2 or states.shape[0] < 1:
        raise EnergyMarginError(f"{where}: states: must be a non-empty (N, D) array, got shape {states.shape}")
    if "model_file" not in group.attrs:
        raise EnergyMarginError(f"{where}: has no attribute 'model_file' (the MuJoCo model's XML)")
    model_file = _text(group.attrs["model_file"])
    if not model_file:
        raise EnergyMarginError(f"{where}: model_file: must be the MuJoCo model's XML as text")
    actions = group.get("actions")
    action_rows = None
    if isinstance(actions, h5py.Dataset) and actions.shape:
        action_rows = int(actions.shape[0])
    return _RawDemo(key, states, model_file, action_rows)


def _env_dt(env_args: Any) -> float | None:
    """1 / ``env_kwargs.control_freq`` of the ``env_args`` JSON attribute, or ``None``."""
    text = _text(env_args)
    if text is None:
        return None
    try:
        parsed = json.loads(text)
    except (ValueError, RecursionError):
        return None
    kwargs = parsed.get("env_kwargs") if isinstance(parsed, dict) else None
    frequency = kwargs.get("control_freq") if isinstance(kwargs, dict) else None
    if isinstance(frequency, bool) or not isinstance(frequency, int | float):
        return None
    if not math.isfinite(frequency) or frequency <= 0:
        return None
    return 1.0 / float(frequency)


def _file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


# -- the models --------------------------------------------------------------------------------


def _robosuite_assets() -> Path | None:
    """The installed robosuite's ``models/assets`` folder, found without importing robosuite."""
    try:
        spec = importlib.util.find_spec("robosuite")
    except (ImportError, ValueError):
        return None
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        folder = Path(location) / "models" / "assets"
        if folder.is_dir():
            return folder
    return None


def reroot_assets(xml: str, *, where: str, assets: Path | None = None, base: Path | None = None) -> str:
    """The model XML with every asset file that does not exist looked for again, as absolute paths.

    Args:
        xml: the model's XML text.
        where: names the model in errors (file and demonstration).
        assets: a folder to look in: the part of a path after ``models/assets/``, else its name.
        base: the folder relative file names are taken from (default: the current folder).

    Returns:
        ``xml`` itself when every asset file exists as written, else the XML with absolute paths.

    Raises:
        EnergyMarginError: the XML is not XML, or an asset file is found nowhere (one line naming it).
    """
    try:
        root = ElementTree.fromstring(xml)
    except ElementTree.ParseError as error:
        raise EnergyMarginError(f"{where}: model_file: is not valid XML ({_one_line(error)})") from None
    folders: dict[str, str] = {}
    for compiler in root.iter("compiler"):
        for name in ("assetdir", "meshdir", "texturedir"):
            if compiler.get(name):
                folders[name] = str(compiler.get(name))
    robosuite = _robosuite_assets()
    changed = False
    for element in root.iter():
        folder_key = _ASSET_ELEMENTS.get(str(element.tag))
        if folder_key is None:
            continue
        attributes = ("file", *_TEXTURE_FACES) if element.tag == "texture" else ("file",)
        folder = folders.get(folder_key, folders.get("assetdir", ""))
        for attribute in attributes:
            value = element.get(attribute)
            if not value:
                continue
            found = _locate(value, folder, base, assets, robosuite)
            if found is None:
                looked = f" or under {assets}" if assets is not None else ""
                looked += f" or under {robosuite}" if robosuite is not None and assets is None else ""
                raise EnergyMarginError(
                    f"{where}: model_file: {element.tag} file {value} does not exist here{looked}; "
                    "pass `assets`, a folder with the model's asset files (robosuite's models/assets)"
                )
            if found != value:
                element.set(attribute, found)
                changed = True
    return ElementTree.tostring(root, encoding="unicode") if changed else xml


def _locate(value: str, folder: str, base: Path | None, assets: Path | None, robosuite: Path | None) -> str | None:
    """The absolute path of asset file ``value`` (as written, or re-rooted), or ``None``."""
    written = Path(value)
    if not written.is_absolute():
        written = Path(folder) / written
        if not written.is_absolute():
            written = (base or Path.cwd()) / written
    try:
        if written.is_file():
            return value if Path(value).is_absolute() else str(written.resolve())
    except OSError:
        pass
    posix = value.replace("\\", "/")
    candidates: list[Path] = []
    if assets is not None:
        if _MODELS_ASSETS in posix:
            candidates.append(assets / posix.split(_MODELS_ASSETS, 1)[1])
        candidates.append(assets / posix.rsplit("/", 1)[-1])
    if robosuite is not None and _ROBOSUITE_ASSETS in posix:
        candidates.append(robosuite / posix.split(_ROBOSUITE_ASSETS, 1)[1])
    for candidate in candidates:
        try:
            if candidate.is_file():
                return str(candidate.resolve())
        except OSError:
            continue
    return None


def compile_xml(xml: str, *, where: str) -> mujoco.MjModel:
    """Compile model XML with ``mujoco.MjSpec``; a failure is one line with MuJoCo's message."""
    try:
        return mujoco.MjSpec.from_string(xml).compile()
    except (ValueError, mujoco.FatalError) as error:
        raise EnergyMarginError(f"{where}: model_file: does not compile: {_one_line(error)}") from None


def _build_models(path: Path, demos: Sequence[_RawDemo], assets: Path | None) -> list[_BuiltModel]:
    """Each demonstration's model (identical texts compiled once); all must be the first one's."""
    cache: dict[str, _BuiltModel] = {}
    built: list[_BuiltModel] = []
    for demo in demos:
        where = f"{path}:/data/{demo.key}"
        if demo.model_file not in cache:
            xml = reroot_assets(demo.model_file, where=where, assets=assets, base=path.parent)
            model = compile_xml(xml, where=where)
            cache[demo.model_file] = _BuiltModel(xml, model, model_hash(model))
        model_built = cache[demo.model_file]
        if built and model_built.sha256 != built[0].sha256:
            raise EnergyMarginError(
                f"{where}: model_file: compiles to another model than {demos[0].key} "
                f"(sha256 {model_built.sha256[:12]}…, {demos[0].key}: {built[0].sha256[:12]}…); "
                "a dataset has one model: split the file into one file per model"
            )
        built.append(model_built)
    return built


# -- the states --------------------------------------------------------------------------------


def _rollout(
    path: Path, demo: _RawDemo, model: mujoco.MjModel, dt: float | None, n_frames: int
) -> tuple[str, dict[str, np.ndarray]]:
    """The demonstration as a checked roll-out ``(name, {time, qpos, qvel})``."""
    where = f"{path}:/data/{demo.key}"
    states = demo.states
    rows, width = states.shape
    nq, nv = int(model.nq), int(model.nv)
    timed = width == 1 + nq + nv
    if timed:
        time, qpos, qvel = states[:, 0], states[:, 1 : 1 + nq], states[:, 1 + nq :]
    elif width == nq + nv:
        if dt is None:
            raise EnergyMarginError(
                f"{where}: states: has {width} columns, nq + nv ({nq} + {nv}) without the time, and the file's "
                "env_args gives no env_kwargs.control_freq: pass `dt`, the seconds between rows"
            )
        time, qpos, qvel = np.arange(rows) * dt, states[:, :nq], states[:, nq:]
    else:
        raise EnergyMarginError(
            f"{where}: states: has {width} columns, expected 1 + nq + nv = {1 + nq + nv} (time, qpos, qvel) "
            f"or nq + nv = {nq + nv} for its model (nq {nq}, nv {nv})"
        )
    bad = np.argwhere(~np.isfinite(states))
    if bad.size:
        raise EnergyMarginError(f"{where}: states: NaN or infinite value at row {int(bad[0][0])}")
    late = np.flatnonzero(np.diff(time) <= 0)
    if timed and late.size:
        row = int(late[0]) + 1
        raise EnergyMarginError(
            f"{where}: states: the time (column 0) does not increase at row {row} ({time[row]} after {time[row - 1]})"
        )
    if demo.action_rows is not None and demo.action_rows != rows:
        raise EnergyMarginError(f"{where}: actions: has {demo.action_rows} rows, states {rows}")
    if rows < n_frames:
        raise EnergyMarginError(f"{where}: states: has {rows} rows, fewer than `n_frames={n_frames}`")
    arrays = check_rollout(where, {"time": time, "qpos": qpos, "qvel": qvel}, model)
    return where, arrays


# -- the scene ---------------------------------------------------------------------------------


def _scene_spec(tables: _Tables, scene_file: Path | str | None, path: Path, duration: float) -> SceneSpec:
    """The validated scene of the recording (its ``mjcf`` names the HDF5 file in messages)."""
    document = dict(tables.document)
    document["mjcf"] = str(path.resolve())
    document["motion"] = {"duration": duration, "robot": ROBOT_DURING_ANALYSIS}
    origin = str(scene_file) if scene_file is not None else "record options"
    return scene_spec_from_tables(document, origin=origin)


def _scene_text(spec: SceneSpec, loaded: LoadedScene, duration: float) -> str:
    """The scene file of the dataset's ``source`` folder (TOML)."""
    document: dict[str, Any] = {
        "objects": {"bodies": list(loaded.object_names), "joints": loaded.spec.object_joints},
        "motion": {"duration": duration, "robot": ROBOT_DURING_ANALYSIS},
        "perturbation": {
            "linear_acceleration": list(loaded.perturbation.linear_acceleration),
            "angular_acceleration": list(loaded.perturbation.angular_acceleration),
            "max_duration": loaded.perturbation.max_duration,
            "lambda": loaded.perturbation.likelihood_lambda,
        },
        "bounds": {
            **({"low": list(spec.bounds_low)} if spec.bounds_low is not None else {}),
            **({"high": list(spec.bounds_high)} if spec.bounds_high is not None else {}),
            "max_speed": spec.max_speed,
        },
        "capture": _with_at_least(spec.capture, spec.capture_at_least),
        "success": _with_at_least(spec.success, spec.success_at_least),
    }
    lines = [
        "# The scene of demonstrations recorded with energy-margin record --format robomimic.",
        f"schema_version = {SCHEMA_VERSION}",
        f"mjcf = {toml_value(MODEL_FILE)}",
    ]
    for table, values in document.items():
        lines.extend(["", f"[{table}]"])
        lines.extend(f"{toml_key(key)} = {toml_value(value)}" for key, value in values.items())
    return "\n".join(lines) + "\n"


def _with_at_least(region: dict[str, Any], at_least: int | None) -> dict[str, Any]:
    return {"region": region} if at_least is None else {"region": region, "at_least": at_least}


# -- the dataset -------------------------------------------------------------------------------


def _write(
    out: Path,
    built: _BuiltModel,
    scene_text: str,
    rollouts: list[tuple[str, dict[str, np.ndarray]]],
    n_frames: int,
    sources: list[dict[str, Any]],
    *,
    overwrite: bool,
    progress: Callable[[int], None] | None,
    drop_unphysical: bool = False,
) -> Dataset:
    """Build the dataset in a sibling of ``out`` with its ``source`` scene, then rename it onto ``out``."""
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = staging_directory(out.parent, out.name)
    try:
        source = staging / SOURCE_FOLDER
        source.mkdir()
        (source / MODEL_FILE).write_text(built.xml, encoding="utf-8")
        (source / SCENE_FILE).write_text(scene_text, encoding="utf-8")
        task = get_task("scene", {"scene_file": str(source / SCENE_FILE)})
        assert isinstance(task, SceneTask)
        if task.loaded.model_sha256 != built.sha256:
            raise EnergyMarginError(
                f"{out}: the model written to {SOURCE_FOLDER}/{MODEL_FILE} does not compile to the recorded model "
                f"(sha256 {task.loaded.model_sha256[:12]}…, recorded {built.sha256[:12]}…)"
            )
        dropped: list[dict[str, str]] | None = [] if drop_unphysical else None
        records = rollout_records(task, rollouts, n_frames=n_frames, progress=progress, dropped=dropped)
        extra: dict[str, Any] = {"recorded_from": sources, **({DROPPED_KEY: dropped} if dropped else {})}
        dataset = records_dataset(task, records, out, engine="mujoco", extra=extra)
        metadata = dict(dataset.metadata)
        metadata["task_config"] = {
            **metadata["task_config"],
            "scene_file": str(out.resolve() / SOURCE_FOLDER / SCENE_FILE),
        }
        write_directory(out, metadata, dataset.arrays, overwrite=overwrite, staging=staging)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return Dataset(path=out, metadata=metadata, arrays=dataset.arrays)
