"""Every difference between the MuJoCo and numpy versions the package supports, in one place.

The package runs on MuJoCo 3.3.0 and later and numpy 1.26.4 and later. Where an older release
spells a thing differently, the helpers below give every caller one spelling:

* ``MjsJoint.damping`` and ``.stiffness`` are three numbers (the first the linear coefficient) from MuJoCo 3.7 and one
  number before: :func:`joint_coefficient`.
* ``MjSpec.delete`` removes any element in later releases; MuJoCo 3.3.0 has
  ``MjSpec.detach_body`` for a body and ``delete`` on each other element: :func:`delete_element`.
  A joint's damping or stiffness is set in place by :func:`set_joint_coefficient`.
* ``MjsActuator.set_to_position`` and geoms and sites added to a frame (``MjsFrame.add_geom``)
  are later additions; MuJoCo 3.3.0 sets the gains by hand and moves an element of the body into
  the frame: :func:`set_to_position` and :func:`add_in_frame`.
* ``MjSpec.to_xml`` writes the spec as it stands in later releases and the last compiled model in
  MuJoCo 3.3.0 (a keyframe added since is left out): :func:`spec_xml`.
* ``MjvLight`` has ``type``, ``intensity``, ``range`` and ``texid`` in later releases and
  ``directional`` instead of ``type`` in MuJoCo 3.3.0: :func:`copy_light`.
* The header of a binary model (``.mjb``) names the MuJoCo release that wrote it from 3.5 (a
  format number before): :data:`MJB_VERSION_SINCE`.
* The mesh and texture folders are ``MjSpec.compiler.meshdir`` and ``.texturedir`` in later
  releases, ``MjSpec.meshdir`` and ``.texturedir`` in MuJoCo 3.3.0: :func:`set_asset_dirs`.
* Copying a body with ``attach_body`` puts each copy at its reference pose in the model's
  keyframes from MuJoCo 3.16; before, it leaves zeros there, and a spec compiled before the copy
  refuses it: :func:`compile_before_copying` and :func:`copy_body`.
* Two boxes face to face report half their depth before MuJoCo 3.4: :func:`contact_depths`
  measures box-box pairs with ``mj_geomDistance`` there.
* ``MjSpec.compile`` turns a warning while compiling (a model unstable at its reference pose) into
  an error before MuJoCo 3.10: :func:`compile_refuses_warnings`.
* ``numpy.savez(allow_pickle=False)`` is an option from numpy 2.2 and an array named
  ``allow_pickle`` before: :func:`save_npz` (which never pickles on any version).

Some differences are the engine's own and cannot be mended here; the tests pin their numbers per
release (``tests/releases.py``) or skip on the releases that lack a behaviour:

* Frictionless contacts (friction 0, clamped to 1e-5) resist sliding in some poses in MuJoCo
  3.3.0 to 3.3.5: :data:`FRICTIONLESS_SLIDING_SINCE`.
* A cylinder whose centre is inside a box touches it without a contact before MuJoCo 4.0:
  :data:`CYLINDER_INSIDE_BOX_SINCE` (the dataset check cannot see such an overlap there).

This module is a foundation like :mod:`energy_margin.errors`: it imports no stage.
"""

from __future__ import annotations

import functools
import os
import re
from collections.abc import Callable, Mapping, Sequence
from typing import IO, Any

import numpy as np

from energy_margin.errors import InvalidDataError, InvalidParameterError

__all__ = [
    "ATTACH_KEYFRAMES_SINCE",
    "BOX_DEPTH_SINCE",
    "COMPILE_WARNINGS_SINCE",
    "CYLINDER_INSIDE_BOX_SINCE",
    "FRICTIONLESS_SLIDING_SINCE",
    "JOINT_COEFFICIENTS_SINCE",
    "MJB_VERSION_SINCE",
    "MUJOCO_MINIMUM",
    "SPEC_XML_SINCE",
    "add_in_frame",
    "attach_keeps_keyframes",
    "compile_before_copying",
    "compile_refuses_warnings",
    "contact_depths",
    "copy_body",
    "copy_light",
    "delete_element",
    "format_version",
    "has_warning_hook",
    "joint_coefficient",
    "mujoco_at_least",
    "mujoco_version",
    "numpy_version",
    "parse_version",
    "reference_pose_in_keyframes",
    "save_npz",
    "set_asset_dirs",
    "set_joint_coefficient",
    "set_to_position",
    "spec_xml",
]

#: The oldest MuJoCo release the package supports (Meta-World 3.1.1 pins it).
MUJOCO_MINIMUM = (3, 3, 0)
#: The first MuJoCo release whose joint damping and stiffness hold three numbers.
JOINT_COEFFICIENTS_SINCE = (3, 7, 0)
#: The first MuJoCo release whose box-box contacts report their whole depth.
BOX_DEPTH_SINCE = (3, 4, 0)
#: The first MuJoCo release whose ``MjSpec.compile`` keeps a warning a warning.
COMPILE_WARNINGS_SINCE = (3, 10, 0)
#: The first MuJoCo release whose frictionless contacts let an object slide freely in every pose.
FRICTIONLESS_SLIDING_SINCE = (3, 3, 6)
#: The first MuJoCo release that finds the contact of a cylinder whose centre is inside a box.
CYLINDER_INSIDE_BOX_SINCE = (4, 0, 0)
#: The first MuJoCo release whose ``MjSpec.to_xml`` writes the spec itself, not the last compiled model.
SPEC_XML_SINCE = (3, 3, 1)
#: The first MuJoCo release whose binary models (``.mjb``) carry its version number in their header.
MJB_VERSION_SINCE = (3, 5, 0)
#: The first MuJoCo release whose ``attach_body`` extends the keyframes of the model attached to.
ATTACH_KEYFRAMES_SINCE = (3, 16, 0)


def parse_version(text: str) -> tuple[int, int, int]:
    """The (major, minor, patch) numbers of a version string such as ``"3.3.0"`` or ``"2.1.0rc1"``.

    Raises:
        InvalidParameterError: ``text`` does not start with a number.

    """
    numbers = [int(match) for match in re.findall(r"\d+", text.split("+")[0])[:3]]
    if not numbers or not re.match(r"\d", text):
        # A defect: the text is an installed package's __version__, never the user's input.
        raise InvalidParameterError("text", f"is not a version: {text!r}")
    padded = [*numbers, 0, 0][:3]
    return padded[0], padded[1], padded[2]


def format_version(version: tuple[int, int, int]) -> str:
    """``(3, 14, 0)`` as ``"3.14.0"``."""
    return ".".join(str(number) for number in version)


@functools.cache
def mujoco_version() -> tuple[int, int, int]:
    """The installed MuJoCo's (major, minor, patch)."""
    import mujoco

    return parse_version(str(mujoco.__version__))


@functools.cache
def numpy_version() -> tuple[int, int, int]:
    """The installed numpy's (major, minor, patch)."""
    return parse_version(np.__version__)


def mujoco_at_least(version: tuple[int, int, int]) -> bool:
    """Whether the installed MuJoCo is ``version`` or later."""
    return mujoco_version() >= version


def joint_coefficient(value: float) -> float | list[float]:
    """A joint's damping or stiffness as ``MjsJoint`` takes it: three numbers from MuJoCo 3.7, else one.

    The second and third numbers (the nonlinear terms) are zero: the same linear
    damping or spring as the single number of older releases.
    """
    if mujoco_at_least(JOINT_COEFFICIENTS_SINCE):
        return [float(value), 0.0, 0.0]
    return float(value)


def set_joint_coefficient(joint: Any, attribute: str, value: float) -> None:
    """Set an ``MjsJoint``'s ``damping`` or ``stiffness`` (the first, linear, number from MuJoCo 3.7)."""
    if mujoco_at_least(JOINT_COEFFICIENTS_SINCE):
        getattr(joint, attribute)[0] = float(value)
    else:
        setattr(joint, attribute, float(value))


def delete_element(spec: Any, element: Any) -> None:
    """Remove ``element`` (a body with its subtree, a joint, a site, an actuator, ...) from ``spec``."""
    if hasattr(spec, "delete"):
        spec.delete(element)
    elif type(element).__name__ == "MjsBody":
        spec.detach_body(element)
    else:
        element.delete()


def set_to_position(actuator: Any, kp: float, kv: float | None = None) -> None:
    """Make ``actuator`` a position servo: force ``kp (ctrl - q) - kv qdot`` (no damping when ``kv`` is ``None``)."""
    if hasattr(actuator, "set_to_position"):
        if kv is None:
            actuator.set_to_position(kp=kp)
        else:
            actuator.set_to_position(kp=kp, kv=kv)
        return
    import mujoco

    actuator.dyntype = mujoco.mjtDyn.mjDYN_NONE
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    gain, bias = np.zeros(10), np.zeros(10)
    gain[0] = kp
    bias[1] = -kp
    bias[2] = -(kv or 0.0)
    actuator.gainprm = gain
    actuator.biasprm = bias


def add_in_frame(body: Any, frame: Any, kind: str, **attributes: Any) -> Any:
    """Add a ``kind`` (``"geom"`` or ``"site"``) with ``attributes`` to ``body`` in its frame ``frame``."""
    if hasattr(frame, f"add_{kind}"):
        return getattr(frame, f"add_{kind}")(**attributes)
    element = getattr(body, f"add_{kind}")(**attributes)
    element.set_frame(frame)
    return element


def spec_xml(spec: Any) -> str:
    """The MJCF text of ``spec`` as it stands (compiled first where ``to_xml`` writes the last compiled model)."""
    if not mujoco_at_least(SPEC_XML_SINCE):
        spec.compile()
    return str(spec.to_xml())


_LIGHT_ARRAYS = ("pos", "dir", "ambient", "diffuse", "specular", "attenuation")
_LIGHT_NUMBERS = (
    "type",
    "directional",
    "castshadow",
    "cutoff",
    "exponent",
    "bulbradius",
    "intensity",
    "range",
    "texid",
)


def copy_light(source: Any, target: Any) -> None:
    """Copy an ``MjvLight``'s position, direction, colours and kind to another (not ``headlight``)."""
    for name in _LIGHT_ARRAYS:
        getattr(target, name)[:] = getattr(source, name)
    for name in _LIGHT_NUMBERS:
        if hasattr(source, name):
            setattr(target, name, getattr(source, name))


def set_asset_dirs(spec: Any, *, meshdir: str | None = None, texturedir: str | None = None) -> None:
    """Set the folders an ``MjSpec`` reads its meshes and textures from (``None``: unchanged)."""
    holder = spec.compiler if hasattr(spec.compiler, "meshdir") else spec
    if meshdir is not None:
        holder.meshdir = meshdir
    if texturedir is not None:
        holder.texturedir = texturedir


def attach_keeps_keyframes() -> bool:
    """Whether ``attach_body`` gives the copies their reference pose in every keyframe (MuJoCo 3.16 on)."""
    return mujoco_at_least(ATTACH_KEYFRAMES_SINCE)


def compile_before_copying(spec: Any) -> Any:
    """Compile ``spec`` to measure it before :func:`copy_body` adds copies to it.

    Before MuJoCo 3.16 a compiled spec that has keyframes refuses ``attach_body`` ("Keyframe
    'start' has invalid qpos size"): there a copy of the spec is compiled instead.
    """
    if attach_keeps_keyframes():
        return spec.compile()
    return spec.copy().compile()


def copy_body(spec: Any, body: Any, positions: Sequence[Sequence[float]], suffixes: Sequence[str]) -> None:
    """Replace ``body`` (a child of the worldbody) by copies at ``positions``, named ``<body><suffix>``.

    Every copy hangs from a new frame of the worldbody at its position; the original is then
    deleted. The keyframes come out as MuJoCo 3.16 and later make them: ``attach_body`` adds one
    keyframe per copy and keyframe (the template's values on that copy), and in every other
    keyframe each copy stands at its reference pose (``qpos0``). Older releases leave zeros
    there, which :func:`reference_pose_in_keyframes` mends.

    Args:
        spec: the ``mujoco.MjSpec`` (``copy_during_attach`` set).
        body: the ``MjsBody`` to copy.
        positions: each copy's frame position, m.
        suffixes: each copy's name suffix.

    """
    n_keys = len(spec.keys)
    for position, suffix in zip(positions, suffixes, strict=True):
        frame = spec.worldbody.add_frame(pos=[float(v) for v in position])
        frame.attach_body(body, "", suffix)
    name = body.name
    delete_element(spec, body)
    if attach_keeps_keyframes() or n_keys == 0 or not suffixes:
        return
    import mujoco

    model = spec.compile()
    roots = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name + suffix) for suffix in suffixes]
    mended = reference_pose_in_keyframes(model, n_keys, roots)
    for key, row in zip(spec.keys, mended, strict=True):
        key.qpos = row


#: qpos entries of each joint type (free, ball, slide, hinge).
_QPOS_SIZE = (7, 4, 1, 1)


def reference_pose_in_keyframes(model: Any, n_keys: int, roots: Sequence[int]) -> np.ndarray:
    """``model.key_qpos`` with each copied body at its ``qpos0`` where its keyframes leave it unset.

    ``attach_body`` orders the keyframes of the copied model as the ``n_keys`` original keyframes
    once per copy (each sets the template's values on that copy only), then the original ones
    (which set no copy). Returns the (nkey, nq) keyframe positions.

    Args:
        model: the compiled ``MjModel`` with the copies.
        n_keys: keyframes of the model before copying.
        roots: body id of each copy's root body, in the order the copies were attached.

    """
    qpos = np.array(model.key_qpos, dtype=np.float64).reshape(model.nkey, model.nq)
    for copy, root in enumerate(roots):
        joints = np.flatnonzero(model.body_rootid[model.jnt_bodyid] == root)
        columns = [
            address
            for joint in joints
            for address in range(
                int(model.jnt_qposadr[joint]), int(model.jnt_qposadr[joint]) + _QPOS_SIZE[model.jnt_type[joint]]
            )
        ]
        for key in range(model.nkey):
            if key // n_keys != copy or key >= n_keys * len(roots):
                qpos[key, columns] = model.qpos0[columns]
    return qpos


def contact_depths(model: Any, data: Any) -> np.ndarray:
    """How deep each of ``data``'s contacts penetrates, m (``-dist``: positive where geoms overlap).

    Before MuJoCo 3.4 the contacts of two boxes face to face carry half their depth. There a
    box-box pair whose deepest contact is shallower than the pair's penetration (``mj_geomDistance``)
    has its contacts' depths scaled up to it, which is what later releases report.
    """
    contacts = data.contact
    depths: np.ndarray = -np.asarray(contacts.dist, dtype=np.float64)
    if mujoco_at_least(BOX_DEPTH_SINCE) or depths.size == 0:
        return depths
    import mujoco

    box = int(mujoco.mjtGeom.mjGEOM_BOX)
    first, second = np.asarray(contacts.geom1), np.asarray(contacts.geom2)
    boxes = (model.geom_type[first] == box) & (model.geom_type[second] == box) & (depths > 0)
    for pair in {(int(first[c]), int(second[c])) for c in np.flatnonzero(boxes)}:
        rows = np.flatnonzero((first == pair[0]) & (second == pair[1]))
        deepest = float(depths[rows].max())
        penetration = -float(mujoco.mj_geomDistance(model, data, pair[0], pair[1], 0.0, None))
        if penetration > deepest * (1.0 + 1e-9):
            depths[rows] *= penetration / deepest
    return depths


def compile_refuses_warnings() -> bool:
    """Whether ``MjSpec.compile`` raises on a warning, e.g. a model unstable at its reference pose (before 3.10)."""
    return not mujoco_at_least(COMPILE_WARNINGS_SINCE)


def has_warning_hook() -> bool:
    """Whether the bindings let a process take MuJoCo's warnings (``mujoco.set_mju_user_warning``)."""
    import mujoco

    return hasattr(mujoco, "set_mju_user_warning")


def save_npz(
    file: str | os.PathLike[str] | IO[bytes], arrays: Mapping[str, np.ndarray], *, compressed: bool = False
) -> None:
    """Write ``arrays`` as one ``.npz`` archive, refusing any array that would need pickling.

    ``numpy.savez`` takes ``allow_pickle`` only from numpy 2.2 (before, it stores an array of that
    name); it pickles only arrays of Python objects, which are refused here on every version.

    Raises:
        InvalidDataError: an array holds Python objects.

    """
    for name, value in arrays.items():
        if np.asarray(value).dtype.hasobject:
            raise InvalidDataError(f"array {name!r} holds Python objects and cannot be saved without pickling")
    # Typed loosely: numpy 2.2's stubs read every keyword as possibly ``allow_pickle``.
    write: Callable[..., None] = np.savez_compressed if compressed else np.savez
    write(file, **arrays)
