"""A scene file's model saved compiled: MuJoCo's binary model format (``.mjb``).

A scene file's ``mjcf`` may name an ``.mjb`` file (written by ``mujoco.mj_saveModel``) instead of
an MJCF: the exact model an environment runs, with whatever its code changed after loading its
XML. It is loaded as compiled, so nothing in the scene file may edit it (``objects.template``,
``[design]``), and only the MuJoCo version that wrote it can read it (the format is
version-specific). :func:`model_differences` names the arrays in which two compiled models differ.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from energy_margin.runs.files import atomic_path
from energy_margin.tasks.scene_spec import SceneSpec

__all__ = ["BINARY_SUFFIX", "is_binary_model", "load_binary_model", "model_differences", "save_binary_model"]

#: The file name suffix of MuJoCo's binary model format.
BINARY_SUFFIX = ".mjb"
#: Integers at the start of an ``.mjb`` file that this MuJoCo checks (its file ID, the size of a
#: real number, the number of sizes and the version).
_HEADER_INTS = 4


def is_binary_model(path: Path | str) -> bool:
    """Whether ``path`` names a binary model (``.mjb``, any case) rather than an MJCF."""
    return Path(path).suffix.lower() == BINARY_SUFFIX


def _own_header() -> np.ndarray:
    """The header integers this MuJoCo writes, read from a tiny model saved to memory."""
    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return np.frombuffer(buffer.tobytes()[: 4 * _HEADER_INTS], dtype=np.int32)


def _version_text(number: int) -> str:
    """``4000000`` as ``4.0.0`` (MuJoCo's version number: major, minor and patch, three digits each)."""
    return f"{number // 1_000_000}.{number // 1000 % 1000}.{number % 1000}"


def _header_problem(path: Path) -> str | None:
    """Why this MuJoCo cannot read the ``.mjb`` at ``path`` from its header alone, or ``None``."""
    try:
        with path.open("rb") as stream:
            start = stream.read(4 * _HEADER_INTS)
    except OSError as error:
        return f"cannot be read ({error.strerror})"
    own = _own_header()
    header = np.frombuffer(start[: 4 * (len(start) // 4)], dtype=np.int32)
    if header.size < 1 or header[0] != own[0]:
        return "is not a MuJoCo binary model (mj_saveModel writes one)"
    if header.size < _HEADER_INTS or np.array_equal(header, own):
        return None
    this = mujoco.mj_versionString()
    written = (
        f"by MuJoCo {_version_text(int(header[3]))}"
        if int(header[3]) != int(own[3]) and int(header[3]) >= 1_000_000
        else "by another MuJoCo version or build"
    )
    return (
        f"was written {written} and this is MuJoCo {this}: a binary model is read only by the MuJoCo that wrote it "
        "(save it again with this version, or name the MJCF)"
    )


def load_binary_model(spec: SceneSpec) -> mujoco.MjModel:
    """The compiled model of a scene file whose ``mjcf`` names an ``.mjb`` (checked to be a file).

    Raises:
        EnergyMarginError: ``objects.template`` or ``[design]`` in the file (both edit an MJCF), an
            ``.mjb`` this MuJoCo cannot read (another version's, or not a binary model); one line
            naming the file, line and key.

    """
    name = spec.mjcf.name
    if spec.template is not None:
        raise spec.error(
            "objects.template", f"needs an MJCF model: {name} is a compiled model (.mjb) whose bodies cannot be copied"
        )
    if spec.design:
        raise spec.error(
            spec.design[0].key,
            f"[design] needs an MJCF model: {name} is a compiled model (.mjb) that cannot be edited and compiled again",
        )
    problem = _header_problem(spec.mjcf)
    if problem is not None:
        raise spec.error("mjcf", f"{name} {problem}")
    warnings: list[str] = []
    previous = mujoco.get_mju_user_warning()
    # MuJoCo's default handler prints warnings and appends them to MUJOCO_LOG.TXT: keep them for the message.
    mujoco.set_mju_user_warning(warnings.append)
    try:
        return mujoco.MjModel.from_binary_path(str(spec.mjcf))
    except (ValueError, mujoco.FatalError) as error:
        reason = "; ".join(" ".join(text.split()) for text in warnings) or " ".join(str(error).split())
        raise spec.error(
            "mjcf", f"{name} cannot be read as a binary model of MuJoCo {mujoco.mj_versionString()} ({reason})"
        ) from None
    finally:
        mujoco.set_mju_user_warning(previous)


def save_binary_model(model: mujoco.MjModel, path: Path) -> None:
    """Write ``model`` to ``path`` in MuJoCo's binary format (``mj_saveModel``), atomically."""
    with atomic_path(path) as temporary:
        mujoco.mj_saveModel(model, str(temporary), None)


def model_differences(first: mujoco.MjModel, second: mujoco.MjModel, *, limit: int = 6) -> list[str]:
    """Names of the fields in which two compiled models differ, at most ``limit`` (empty: none found).

    Sizes are compared first (``"nbody 12 != 13"``); models of the same sizes are compared array by
    array (``"eq_data"``, ``"site_pos"``; NaN equals NaN) and in their physics options
    (``"opt.timestep"``). Other differences (visual settings, statistics) are not named.
    """
    # The sizes: nq, nbody, nnames, ... (nbuffer and nnames_map follow from them).
    sizes = [
        f"{name} {getattr(first, name)} != {getattr(second, name)}"
        for name in dir(first)
        if name.startswith("n")
        and name not in ("nbuffer", "nnames_map")
        and isinstance(getattr(first, name), int)
        and getattr(first, name) != getattr(second, name, None)
    ]
    if sizes:
        return sizes[:limit]
    found: list[str] = []
    for prefix, one, other in (("", first, second), ("opt.", first.opt, second.opt)):
        for name in dir(one):
            if name.startswith("_"):
                continue
            try:
                a, b = getattr(one, name), getattr(other, name)
            except Exception:  # an attribute that cannot be read: not a field
                continue
            if isinstance(a, float | int) and not isinstance(a, bool):
                a, b = np.asarray(a), np.asarray(b)
            if not isinstance(a, np.ndarray) or not isinstance(b, np.ndarray):
                continue
            if a.shape != b.shape or not np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"):
                found.append(prefix + name)
    return found[:limit]
