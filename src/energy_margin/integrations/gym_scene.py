"""A starter scene file from a Gymnasium environment (``energy-margin scene --from-gym ENV_ID``).

The environment's model is saved beside the scene file (:func:`save_model`): a copy of the XML the
environment names in ``env.unwrapped.fullpath`` (its asset folders and included files made
absolute so the copy compiles anywhere) when that copy compiles to the environment's model, else
the environment's compiled model itself as an ``.mjb`` file (an environment that changed its model
after loading the XML, or built it in memory). The scene file
declares the objects, the actuators (listed in comments, named in ``motion.actuators`` when every
one has a name), a motion as long as one episode without keyframes,
and a starter capture region around the end effector and a success region around a goal body or
site when the model has one. The regions are a starting point for the user to edit: what the end
effector is, and how close counts as captured, are guesses from names and sizes, printed by
:func:`scene_from_environment`.
"""

from __future__ import annotations

import fnmatch
import os
import tempfile
import tomllib
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.runs.files import atomic_path, file_mode
from energy_margin.sim.mujoco_index import object_owners
from energy_margin.tasks.model_file import BINARY_SUFFIX, model_differences, save_binary_model
from energy_margin.tasks.scene_defaults import DEFAULTS
from energy_margin.tasks.scene_file import scene_spec_from_tables
from energy_margin.tasks.scene_model import model_hash, resolve_scene
from energy_margin.tasks.scene_toml import toml_value

__all__ = ["END_EFFECTOR_WORDS", "GOAL_WORDS", "StarterScene", "save_model", "scene_from_environment"]

#: Name fragments of an end effector's body or site, most specific first.
END_EFFECTOR_WORDS = ("end_effector", "eef", "fingertip", "tip", "grip", "finger", "hand", "palm", "wrist", "ee")
#: Name fragments of a goal body or site.
GOAL_WORDS = ("goal", "target")


@dataclass(frozen=True)
class StarterScene:
    """What :func:`scene_from_environment` wrote and guessed.

    Attributes:
        scene_file: the scene file.
        model_file: the model saved beside it.
        objects: object body names.
        end_effector: ``(kind, name)`` of the capture region's centre.
        goal: ``(kind, name)`` of the success region's centre, or ``None`` (then a height region).
        capture_radius: radius of the starter capture region, m.
        same_model: whether the saved model compiles to the environment's model (same hash).
        model_note: which model file was written and why (one line, :func:`save_model`).

    """

    scene_file: Path
    model_file: Path
    objects: tuple[str, ...]
    end_effector: tuple[str, str]
    goal: tuple[str, str] | None
    capture_radius: float
    same_model: bool
    model_note: str


def _names(model: mujoco.MjModel, kind: mujoco.mjtObj, count: int) -> list[str]:
    return [mujoco.mj_id2name(model, kind, i) or "" for i in range(count)]


def _descendants(model: mujoco.MjModel, roots: set[int]) -> set[int]:
    found = set(roots)
    for body in range(1, model.nbody):
        parent = int(model.body_parentid[body])
        if parent in found:
            found.add(body)
    return found


def _robot_bodies(model: mujoco.MjModel, objects: set[int]) -> list[int]:
    """Bodies moved by a robot joint or a mocap body, children included, objects excluded."""
    moved = {int(model.jnt_bodyid[j]) for j in range(model.njnt)} | {
        b for b in range(model.nbody) if model.body_mocapid[b] >= 0
    }
    return sorted(_descendants(model, moved - objects) - objects - {0})


def _depth(model: mujoco.MjModel, body: int) -> int:
    depth = 0
    while body:
        body = int(model.body_parentid[body])
        depth += 1
    return depth


def _find(model: mujoco.MjModel, words: tuple[str, ...], bodies: list[int]) -> tuple[str, str] | None:
    """The deepest body (or a site on one of ``bodies``) whose name holds the earliest of ``words``."""
    body_names = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    site_names = _names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite)
    for word in words:
        sites = [s for s in range(model.nsite) if word in site_names[s].lower() and int(model.site_bodyid[s]) in bodies]
        if sites:
            best = max(sites, key=lambda s: _depth(model, int(model.site_bodyid[s])))
            return "site", site_names[best]
        matching = [b for b in bodies if word in body_names[b].lower()]
        if matching:
            return "body", body_names[max(matching, key=lambda b: _depth(model, b))]
    return None


def _portable_xml(source: Path) -> str:
    """The MJCF at ``source`` with its file references made absolute, so a copy compiles anywhere.

    The text is kept as written (only the compiler's ``meshdir``, ``texturedir`` and ``assetdir``
    and the ``<include>`` files become absolute paths), so the copy compiles to the same numbers:
    ``MjSpec.to_xml`` in MuJoCo 4.0.0 writes six significant digits (Pusher's shoulder range
    1.714602 came back as 1.7146).

    Raises:
        EnergyMarginError: the file cannot be read or parsed as XML.

    """
    folder = source.parent.resolve()
    try:
        tree = ElementTree.parse(source)
    except (OSError, ElementTree.ParseError) as error:
        raise EnergyMarginError(f"{source.name} cannot be read ({error})") from None
    root = tree.getroot()
    compiler = root.find("compiler")
    if compiler is None:
        compiler = ElementTree.Element("compiler")
        root.insert(0, compiler)
    assets = compiler.get("assetdir", "")
    for attribute in ("meshdir", "texturedir"):
        compiler.set(attribute, str((folder / (compiler.get(attribute) or assets)).resolve()))
    if "assetdir" in compiler.attrib:
        compiler.set("assetdir", str((folder / assets).resolve()))
    for include in root.iter("include"):
        if include.get("file"):
            include.set("file", str((folder / str(include.get("file"))).resolve()))
    return ElementTree.tostring(root, encoding="unicode")


def save_model(model: mujoco.MjModel, source: Path | None, out: Path) -> tuple[Path, str]:
    """Save the environment's compiled ``model`` beside a scene file; the file written and a line saying why.

    The model file the environment loaded (``source``) is copied to ``out`` with ``.xml``
    (:func:`_portable_xml`) when the copy compiles to ``model`` (same :func:`model_hash`): an MJCF
    is readable and works with any MuJoCo version. Otherwise (no ``source``, a copy that does not
    compile, or a model the environment changed after loading it) ``model`` itself, as it is now,
    goes to ``out`` with ``.mjb`` (``mujoco.mj_saveModel``), which only this MuJoCo version reads.
    Only the file named is written, in ``out``'s folder (which must exist).
    """
    xml_file, binary_file = out.with_suffix(".xml"), out.with_suffix(BINARY_SUFFIX)
    if source is None:
        reason = "the environment names no model file to copy (env.unwrapped.fullpath): its model was built in memory"
    else:
        copied: mujoco.MjModel | None = None
        handle, name = tempfile.mkstemp(dir=out.parent, prefix=f".{xml_file.name}.", suffix=".xml")
        os.close(handle)
        temporary = Path(name)
        try:
            temporary.write_text(_portable_xml(source))
            copied = mujoco.MjSpec.from_file(str(temporary)).compile()
        except EnergyMarginError as error:
            reason = str(error)
        except (ValueError, mujoco.FatalError) as error:
            reason = f"the copy of {source.name} does not compile ({' '.join(str(error).split())})"
        try:
            if copied is not None and model_hash(copied) == model_hash(model):
                temporary.chmod(file_mode())
                os.replace(temporary, xml_file)
                return xml_file, f"wrote {xml_file} (the environment's model file, same model)"
        finally:
            temporary.unlink(missing_ok=True)
        if copied is not None:
            fields = model_differences(copied, model)
            changed = f"{', '.join(fields)} {'differs' if len(fields) == 1 else 'differ'}" if fields else "it differs"
            reason = f"the environment changed its model after loading {source.name} ({changed})"
    save_binary_model(model, binary_file)
    return binary_file, f"wrote {binary_file}: {reason}"


def scene_from_environment(
    env: Any,
    *,
    objects: str | list[str],
    out: str | Path,
    capture_radius: float | None = None,
) -> StarterScene:
    """Write a starter scene file for a Gymnasium MuJoCo environment, its model saved beside it.

    Args:
        env: the environment (its MuJoCo model is found with
            :func:`~energy_margin.integrations.handles.find_mujoco`; ``env.unwrapped.fullpath``,
            where it has one, names the model file it loaded).
        objects: object body names or glob patterns.
        out: the scene file to write (``.toml``); the model goes to the same name with ``.xml``
            or ``.mjb`` (:func:`save_model`).
        capture_radius: radius of the starter capture region, m; ``None``: twice the largest
            object's bounding radius plus 5 cm.

    Raises:
        EnergyMarginError: no MuJoCo model, objects matching nothing, a scene the model refuses;
            nothing is written then.

    """
    from energy_margin.integrations.gymnasium import environment_name, mujoco_handles

    model, _ = mujoco_handles(env)
    name = environment_name(env)
    unwrapped = getattr(env, "unwrapped", env)
    fullpath = getattr(unwrapped, "fullpath", None)
    source = Path(fullpath) if isinstance(fullpath, str | Path) and Path(fullpath).is_file() else None
    patterns = [objects] if isinstance(objects, str) else list(objects)
    body_names = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    chosen = [b for b in range(1, model.nbody) if any(fnmatch.fnmatchcase(body_names[b], p) for p in patterns)]
    if not chosen:
        raise InvalidParameterError(
            "objects", f"{','.join(patterns)}: no body of {name} matches (bodies: {', '.join(body_names[1:])})"
        )
    out = Path(out)
    end_effector = _end_effector(model, name, chosen, body_names)
    every_body = [b for b in range(1, model.nbody) if b not in chosen and body_names[b]]
    goal = _find(model, GOAL_WORDS, every_body)
    radius, capture, success = _regions(model, chosen, end_effector, goal, capture_radius)
    steps = getattr(getattr(env, "spec", None), "max_episode_steps", None) or 100
    duration = float(steps) * float(getattr(unwrapped, "dt", model.opt.timestep))
    text = _scene_text(model, patterns, duration, end_effector, goal, radius, capture, success)
    # The file is checked against the environment's model before anything is written.
    document = tomllib.loads(text)
    resolve_scene(scene_spec_from_tables(document, origin=str(out)), model)
    out.parent.mkdir(parents=True, exist_ok=True)
    model_file, note = save_model(model, source, out)
    saved = mujoco.MjModel.from_binary_path(str(model_file)) if model_file.suffix == BINARY_SUFFIX else None
    with atomic_path(out) as temporary:
        temporary.write_text(
            f"# A starter scene for {name}, written by energy-margin scene --from-gym: edit the regions.\n"
            f"schema_version = 1\nmjcf = {toml_value(model_file.name)}\n{text}"
        )
    return StarterScene(
        scene_file=out,
        model_file=model_file,
        objects=tuple(body_names[b] for b in chosen),
        end_effector=end_effector,
        goal=goal,
        capture_radius=radius,
        same_model=saved is None or model_hash(saved) == model_hash(model),
        model_note=note,
    )


def _end_effector(model: mujoco.MjModel, name: str, chosen: list[int], body_names: list[str]) -> tuple[str, str]:
    """The ``(kind, name)`` the capture region is centred on: a named end-effector, else the deepest robot body.

    Raises:
        EnergyMarginError: the model has no named robot body.
    """
    # Regions name their bodies: only named robot bodies can carry the capture region.
    robot = [body for body in _robot_bodies(model, set(chosen)) if body_names[body]]
    end_effector = _find(model, END_EFFECTOR_WORDS, robot)
    if end_effector is None:
        if not robot:
            raise EnergyMarginError(
                f"{name}: no named robot body (one moved by a joint or a mocap body, not an object) to centre "
                "a capture region on"
            )
        end_effector = ("body", body_names[max(robot, key=lambda b: _depth(model, b))])
    return end_effector


def _regions(
    model: mujoco.MjModel,
    chosen: list[int],
    end_effector: tuple[str, str],
    goal: tuple[str, str] | None,
    capture_radius: float | None,
) -> tuple[float, dict[str, Any], dict[str, Any]]:
    """The capture radius (m) and the starter capture and success region tables.

    Captured: within the radius of the end-effector; success: near the goal, or else above the
    objects' start height less 5 cm. The sizes follow the objects' extent (their geoms' reach, m).
    """
    geoms = np.flatnonzero(object_owners(model, chosen)[model.geom_bodyid] >= 0)
    size = (
        float(np.max(np.linalg.norm(model.geom_pos[geoms], axis=1) + model.geom_rbound[geoms])) if geoms.size else 0.05
    )
    radius = capture_radius if capture_radius is not None else round(2.0 * size + 0.05, 3)
    capture = {"type": "distance", end_effector[0]: end_effector[1], "max": radius}
    success: dict[str, Any]
    if goal is not None:
        success = {"type": "distance", goal[0]: goal[1], "max": round(2.0 * size, 3)}
    else:
        heights = [float(model.body_pos[b][2]) for b in chosen]
        success = {"type": "height", "min": round(min(heights) - 0.05, 3)}
    return radius, capture, success


def _scene_text(
    model: mujoco.MjModel,
    patterns: list[str],
    duration: float,
    end_effector: tuple[str, str],
    goal: tuple[str, str] | None,
    radius: float,
    capture: dict[str, Any],
    success: dict[str, Any],
) -> str:
    """The starter scene file's tables, commented (without its header: schema and model file)."""
    lines = [
        "",
        "[objects]",
        f"bodies = {toml_value(patterns)}",
        "",
        "# One episode; no keyframes: record a roll-out's own commands with the Gymnasium wrapper.",
        *_actuator_comments(model),
        "[motion]",
        f"duration = {toml_value(duration)}",
        *_actuator_names(model),
        "",
        "# The default perturbation: pushes in the world x-y plane and a torque about z, for objects resting",
        "# on a horizontal surface (docs/howto/scenes.md); give z a bound for objects that are lifted.",
        "[perturbation]",
        f"linear_acceleration = {toml_value(list(DEFAULTS['linear_acceleration']))}",
        f"angular_acceleration = {toml_value(list(DEFAULTS['angular_acceleration']))}",
        f"max_duration = {toml_value(DEFAULTS['max_duration'])}",
        "",
        f"# Captured: every object within {radius} m of {end_effector[0]} {end_effector[1]!r} (a guess).",
        "[capture]",
        f"region = {toml_value(capture)}",
        "",
        "# Success: "
        + (
            f"every object within {success.get('max')} m of {goal[0]} {goal[1]!r}."
            if goal
            else "every object above its start height less 5 cm (no goal found)."
        ),
        "[success]",
        f"region = {toml_value(success)}",
        "",
    ]
    return "\n".join(lines)


_TRANSMISSIONS = {
    int(mujoco.mjtTrn.mjTRN_JOINT): (mujoco.mjtObj.mjOBJ_JOINT, "joint"),
    int(mujoco.mjtTrn.mjTRN_JOINTINPARENT): (mujoco.mjtObj.mjOBJ_JOINT, "joint"),
    int(mujoco.mjtTrn.mjTRN_TENDON): (mujoco.mjtObj.mjOBJ_TENDON, "tendon"),
    int(mujoco.mjtTrn.mjTRN_SITE): (mujoco.mjtObj.mjOBJ_SITE, "site"),
    int(mujoco.mjtTrn.mjTRN_BODY): (mujoco.mjtObj.mjOBJ_BODY, "body"),
}


def _actuator_comments(model: mujoco.MjModel) -> list[str]:
    """One comment line per actuator: its index, name, what it drives and its control range."""
    lines = [f"# The model's {model.nu} actuators, in the order of a keyframe's ctrl:"]
    for actuator in range(model.nu):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator) or "(unnamed)"
        kind, word = _TRANSMISSIONS.get(int(model.actuator_trntype[actuator]), (None, "target"))
        target = mujoco.mj_id2name(model, kind, int(model.actuator_trnid[actuator, 0])) if kind is not None else None
        low, high = model.actuator_ctrlrange[actuator]
        limited = bool(model.actuator_ctrllimited[actuator])
        bounds = f"ctrl in [{low:g}, {high:g}]" if limited else "ctrl unbounded"
        lines.append(f"#   {actuator}: {name} -> {word} {target or '?'}, {bounds}")
    return lines if model.nu else []


def _actuator_names(model: mujoco.MjModel) -> list[str]:
    """``actuators = [...]`` when every actuator has a name (the columns of a keyframe's ctrl)."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
    if not names or not all(names):
        return []
    return [f"actuators = {toml_value(names)}"]
