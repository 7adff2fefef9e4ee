"""The version differences of energy_margin.compat, each checked on the MuJoCo and numpy installed.

The oldest CI leg runs these on MuJoCo 3.3.0 and numpy 1.26.4, the newest on the current
releases: each test states what must hold on both.
"""

from __future__ import annotations

import io
import zipfile

import mujoco
import numpy as np
import pytest

from energy_margin import compat
from energy_margin.errors import EnergyMarginError

MODEL = """<mujoco>
  <worldbody>
    <body name="slider" pos="0 0.8 0.03"><joint name="slide" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.02 0.02 0.02" mass="0.5"/></body>
    <body name="box" pos="-0.06 0 0.03" quat="0.9 0 0 0.1"><freejoint/>
      <geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>
    <body name="arm" pos="0 0.5 0.03"><joint name="hinge" type="hinge" axis="0 0 1" ref="0.3"/>
      <geom type="box" size="0.02 0.02 0.02" mass="1"/></body>
  </worldbody>
  <keyframe>
    <key name="start" qpos="0.1 0.01 0.02 0.03 1 0 0 0 0.7" qvel="0.5 1 2 3 4 5 6 0.2"/>
    <key name="end" time="1" qpos="0.2 0.5 0 0.03 1 0 0 0 0.5"/>
  </keyframe>
</mujoco>"""
#: The box's values in both keyframes.
BOX_IN_KEYS = np.array([[0.01, 0.02, 0.03, 1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.03, 1.0, 0.0, 0.0, 0.0]])


@pytest.mark.parametrize(
    ("text", "version"),
    [("3.3.0", (3, 3, 0)), ("4.0", (4, 0, 0)), ("2.1.0rc1", (2, 1, 0)), ("2.13.0+cpu", (2, 13, 0)), ("1", (1, 0, 0))],
)
def test_versions_are_parsed_to_three_numbers(text: str, version: tuple[int, int, int]) -> None:
    assert compat.parse_version(text) == version


def test_a_version_without_numbers_is_refused() -> None:
    with pytest.raises(ValueError, match="not a version: 'dev'"):
        compat.parse_version("dev")


def test_installed_versions_are_read() -> None:
    assert compat.mujoco_version() == compat.parse_version(mujoco.__version__)
    assert compat.numpy_version() == compat.parse_version(np.__version__)
    assert compat.mujoco_version() >= compat.MUJOCO_MINIMUM


def test_a_newer_mujoco_than_installed_is_refused_in_one_line() -> None:
    compat.require_mujoco(compat.MUJOCO_MINIMUM, "anything")
    with pytest.raises(EnergyMarginError) as error:
        compat.require_mujoco((99, 1, 0), "the thing")
    installed = compat.format_version(compat.mujoco_version())
    assert str(error.value) == f"the thing needs MuJoCo 99.1.0 or later (installed: {installed})"


def test_joint_damping_and_stiffness_take_the_installed_spelling() -> None:
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b")
    body.add_geom(size=[0.1, 0.0, 0.0])
    damping, stiffness = compat.joint_coefficient(0.25), compat.joint_coefficient(3.0)
    body.add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE, damping=damping, stiffness=stiffness)
    model = spec.compile()
    assert float(np.ravel(model.dof_damping)[0]) == 0.25
    assert float(np.ravel(model.jnt_stiffness)[0]) == 3.0
    if compat.mujoco_at_least(compat.JOINT_POLYNOMIAL_SINCE):
        assert damping == [0.25, 0.0, 0.0] and stiffness == [3.0, 0.0, 0.0]
    else:
        assert damping == 0.25 and stiffness == 3.0


def test_a_deleted_body_leaves_the_model() -> None:
    spec = mujoco.MjSpec.from_string(MODEL)
    compat.delete_body(spec, spec.body("arm"))
    model = spec.compile()
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "arm") == -1
    assert model.nbody == 3 and model.nq == 8


def _copied(count: int) -> tuple[mujoco.MjSpec, mujoco.MjModel]:
    spec = mujoco.MjSpec.from_string(MODEL)
    # The spec is compiled before copying, as load_scene measures the template first.
    probe = compat.compile_before_copying(spec)
    assert probe.nq == 9 and probe.nkey == 2
    spec.copy_during_attach = True
    compat.copy_body(
        spec, spec.body("box"), [(0.1 * i, 0.0, 0.0) for i in range(count)], [f"_{i}" for i in range(count)]
    )
    return spec, spec.compile()


def _box_columns(model: mujoco.MjModel, name: str) -> slice:
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    address = int(model.jnt_qposadr[model.body_jntadr[body]])
    return slice(address, address + 7)


def test_copies_stand_at_their_reference_pose_in_the_keyframes() -> None:
    _, model = _copied(3)
    names = [model.key(k).name for k in range(model.nkey)]
    assert names == ["start_0", "end_0", "start_1", "end_1", "start_2", "end_2", "start", "end"]
    assert model.nq == 2 + 3 * 7
    for key in range(model.nkey):
        original = key % 2
        # The slider and the hinge keep the keyframe's values in every keyframe.
        np.testing.assert_array_equal(model.key_qpos[key, :2], [[0.1, 0.7], [0.2, 0.5]][original])
        for copy in range(3):
            columns = _box_columns(model, f"box_{copy}")
            expected = BOX_IN_KEYS[original] if key // 2 == copy else model.qpos0[columns]
            np.testing.assert_array_equal(model.key_qpos[key, columns], expected)
    # The copies are side by side at 0.1 m spacing, the template's orientation kept.
    starts = [model.qpos0[_box_columns(model, f"box_{copy}")] for copy in range(3)]
    np.testing.assert_allclose([start[0] for start in starts], [-0.06, 0.04, 0.14], atol=1e-15)
    assert all(np.array_equal(start[3:], starts[0][3:]) for start in starts)
    # Velocities: the keyframe's own for the slider and the hinge, the box's on its own copy only.
    np.testing.assert_array_equal(model.key_qvel[6], [0.5, 0.2, *[0.0] * 18])
    np.testing.assert_array_equal(model.key_qvel[2], [0.5, 0.2, *[0.0] * 6, 1, 2, 3, 4, 5, 6, *[0.0] * 6])


def test_a_copied_spec_compiles_again_with_the_same_keyframes() -> None:
    spec, model = _copied(2)
    again = spec.compile()
    np.testing.assert_array_equal(again.key_qpos, model.key_qpos)
    np.testing.assert_array_equal(again.key_qvel, model.key_qvel)


def test_unset_keyframe_entries_of_copies_are_mended_to_the_reference_pose() -> None:
    # What MuJoCo before 3.16 compiles: zeros (and a unit quaternion) where a keyframe sets no copy.
    _, model = _copied(2)
    older = model.key_qpos.copy()
    for copy in range(2):
        columns = _box_columns(model, f"box_{copy}")
        for key in range(model.nkey):
            if key // 2 != copy:
                older[key, columns] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    model.key_qpos[:] = older
    roots = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"box_{copy}") for copy in range(2)]
    mended = compat.reference_pose_in_keyframes(model, 2, roots)
    for copy in range(2):
        columns = _box_columns(model, f"box_{copy}")
        for key in range(model.nkey):
            expected = BOX_IN_KEYS[key % 2] if key // 2 == copy else model.qpos0[columns]
            np.testing.assert_array_equal(mended[key, columns], expected)
    np.testing.assert_array_equal(mended[:, :2], older[:, :2])


def test_npz_archives_hold_exactly_the_arrays_given() -> None:
    arrays = {"a": np.arange(3.0), "b": np.array("text"), "c": np.zeros((2, 2), dtype=np.int32)}
    for compressed in (False, True):
        stream = io.BytesIO()
        compat.save_npz(stream, arrays, compressed=compressed)
        stream.seek(0)
        with zipfile.ZipFile(stream) as archive:
            assert archive.namelist() == ["a.npy", "b.npy", "c.npy"]
            kinds = {info.compress_type for info in archive.infolist()}
        assert kinds == {zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED}
        stream.seek(0)
        with np.load(stream, allow_pickle=False) as stored:
            for name, value in arrays.items():
                np.testing.assert_array_equal(stored[name], value)
                assert stored[name].dtype == value.dtype


def test_npz_archives_never_pickle() -> None:
    with pytest.raises(ValueError, match="array 'bad' holds Python objects"):
        compat.save_npz(io.BytesIO(), {"good": np.ones(2), "bad": np.array([{"x": 1}], dtype=object)})
