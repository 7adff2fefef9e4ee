"""The version differences of energy_margin.compat, each checked on the MuJoCo and numpy installed.

The oldest CI leg runs these on MuJoCo 3.3.0 and numpy 1.26.4, the newest on the current
releases: each test states what must hold on both.
"""

from __future__ import annotations

import io
import re
import zipfile
from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin import compat
from energy_margin.errors import InvalidDataError, InvalidParameterError

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
    with pytest.raises(InvalidParameterError, match="text is not a version: 'dev'"):
        compat.parse_version("dev")


def test_installed_versions_are_read() -> None:
    assert compat.mujoco_version() == compat.parse_version(mujoco.__version__)
    assert compat.numpy_version() == compat.parse_version(np.__version__)
    assert compat.mujoco_version() >= compat.MUJOCO_MINIMUM


def test_joint_damping_and_stiffness_take_the_installed_spelling() -> None:
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b")
    body.add_geom(size=[0.1, 0.0, 0.0])
    damping, stiffness = compat.joint_coefficient(0.25), compat.joint_coefficient(3.0)
    body.add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE, damping=damping, stiffness=stiffness)
    model = spec.compile()
    assert float(np.ravel(model.dof_damping)[0]) == 0.25
    assert float(np.ravel(model.jnt_stiffness)[0]) == 3.0
    if compat.mujoco_at_least(compat.JOINT_COEFFICIENTS_SINCE):
        assert damping == [0.25, 0.0, 0.0] and stiffness == [3.0, 0.0, 0.0]
    else:
        assert damping == 0.25 and stiffness == 3.0


def test_a_deleted_body_leaves_the_model() -> None:
    spec = mujoco.MjSpec.from_string(MODEL)
    compat.delete_element(spec, spec.body("arm"))
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
    with pytest.raises(InvalidDataError, match="array 'bad' holds Python objects"):
        compat.save_npz(io.BytesIO(), {"good": np.ones(2), "bad": np.array([{"x": 1}], dtype=object)})


BOXES = """<mujoco><worldbody>
<body pos="0 0 0.5"><freejoint/><geom type="box" size="0.005 0.005 0.005"/></body>
<body pos="0.007 0 0.5"><freejoint/><geom type="box" size="0.005 0.005 0.005"/></body>
<body pos="0.3 0 0.5" euler="0 0 0.3"><freejoint/><geom type="box" size="0.05 0.03 0.02"/></body>
<body pos="0.37 0.02 0.51" euler="0.2 0.1 0.5"><freejoint/><geom type="box" size="0.04 0.03 0.02"/></body>
<body pos="1 0 0.5"><freejoint/><geom type="sphere" size="0.01"/></body>
<body pos="1.015 0 0.5"><freejoint/><geom type="sphere" size="0.01"/></body>
</worldbody></mujoco>"""


def test_box_contacts_report_their_whole_depth() -> None:
    model = mujoco.MjModel.from_xml_string(BOXES)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    depths = compat.contact_depths(model, data)
    pairs = list(zip(data.contact.geom1.tolist(), data.contact.geom2.tolist(), strict=True))
    face_to_face = [depth for depth, pair in zip(depths, pairs, strict=True) if set(pair) == {0, 1}]
    # Two 1 cm cubes 7 mm apart: 3 mm deep on every release (MuJoCo 3.3 reports 1.5 mm itself).
    assert face_to_face and np.allclose(face_to_face, 0.003, rtol=0, atol=1e-12)
    raw = -data.contact.dist[[set(pair) == {0, 1} for pair in pairs]]
    assert np.allclose(raw, 0.003 if compat.mujoco_at_least(compat.BOX_DEPTH_SINCE) else 0.0015, atol=1e-12)
    # The other contacts keep the engine's depth: the tilted boxes (whose deepest point is the
    # pair's penetration) and the spheres (5 mm deep).
    others = [index for index, pair in enumerate(pairs) if set(pair) != {0, 1}]
    np.testing.assert_array_equal(depths[others], -data.contact.dist[others])
    assert np.isclose(depths[pairs.index((4, 5))], 0.005, atol=1e-12)
    assert depths.dtype == np.float64 and depths.shape == (data.ncon,)


def test_no_contact_no_depths() -> None:
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert compat.contact_depths(model, data).shape == (0,)


def test_a_model_unstable_at_its_reference_pose_compiles_from_mujoco_3_10() -> None:
    unstable = (
        '<mujoco><option gravity="0 0 -1e200"/><worldbody><body><freejoint/><geom size="0.1"/></body>'
        "</worldbody></mujoco>"
    )
    spec = mujoco.MjSpec.from_string(unstable)
    if compat.compile_refuses_warnings():
        with pytest.raises(ValueError, match="Nan, Inf or huge value in QACC"):
            spec.compile()
    else:
        assert spec.compile().nq == 7


ELEMENTS = """<mujoco><worldbody><body name="b"><joint name="j" damping="0.5" stiffness="2"/><geom size="0.1"/>
<site name="s"/></body></worldbody><actuator><motor name="a" joint="j"/></actuator></mujoco>"""


def test_elements_of_every_kind_are_deleted() -> None:
    spec = mujoco.MjSpec.from_string(ELEMENTS)
    for element in (spec.actuator("a"), spec.site("s"), spec.joint("j")):
        compat.delete_element(spec, element)
    model = spec.compile()
    assert (model.nu, model.nsite, model.njnt, model.nbody) == (0, 0, 0, 2)


def test_a_joint_coefficient_is_set_in_place() -> None:
    spec = mujoco.MjSpec.from_string(ELEMENTS)
    compat.set_joint_coefficient(spec.joint("j"), "damping", 0.75)
    compat.set_joint_coefficient(spec.joint("j"), "stiffness", 4.0)
    model = spec.compile()
    assert float(np.ravel(model.dof_damping)[0]) == 0.75 and float(np.ravel(model.jnt_stiffness)[0]) == 4.0


@pytest.mark.parametrize("kv", [None, 3.0])
def test_a_position_servo_pulls_to_its_target(kv: float | None) -> None:
    spec = mujoco.MjSpec.from_string(ELEMENTS)
    compat.set_to_position(spec.actuator("a"), kp=50.0, kv=kv)
    model = spec.compile()
    np.testing.assert_array_equal(model.actuator_gainprm[0, :3], [50.0, 0.0, 0.0])
    np.testing.assert_array_equal(model.actuator_biasprm[0, :3], [0.0, -50.0, -(kv or 0.0)])
    assert model.actuator_gaintype[0] == mujoco.mjtGain.mjGAIN_FIXED
    assert model.actuator_biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE
    assert model.actuator_dyntype[0] == mujoco.mjtDyn.mjDYN_NONE
    data = mujoco.MjData(model)
    data.qpos[0], data.qvel[0], data.ctrl[0] = 0.1, 1.0, 0.3
    mujoco.mj_forward(model, data)
    assert data.actuator_force[0] == pytest.approx(50.0 * (0.3 - 0.1) - (kv or 0.0) * 1.0)


def test_geoms_and_sites_are_placed_in_a_frame() -> None:
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b", pos=[0.0, 0.0, 1.0])
    frame = body.add_frame(pos=[0.5, 0.0, 0.0], quat=[0.0, 0.0, 0.0, 1.0])
    compat.add_in_frame(body, frame, "geom", name="g", pos=[0.1, 0.0, 0.0], size=[0.05, 0.0, 0.0])
    compat.add_in_frame(body, frame, "site", name="s", pos=[0.0, 0.2, 0.0])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # The frame turns by pi about z: its x and y point the other way.
    np.testing.assert_allclose(data.geom_xpos[0], [0.4, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(data.site_xpos[0], [0.5, -0.2, 1.0], atol=1e-12)


def _folders(spec: mujoco.MjSpec) -> dict[str, str]:
    """The compiler's meshdir and texturedir as the spec writes them (MuJoCo 3.3 adds a slash)."""
    spec.compile()
    return {name: value.rstrip("/") for name, value in re.findall(r'(meshdir|texturedir)="([^"]*)"', spec.to_xml())}


def test_mesh_and_texture_folders_are_set(tmp_path: Path) -> None:
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(size=[0.1, 0.0, 0.0])
    compat.set_asset_dirs(spec, meshdir=str(tmp_path / "meshes"), texturedir=str(tmp_path / "textures"))
    assert _folders(spec) == {"meshdir": str(tmp_path / "meshes"), "texturedir": str(tmp_path / "textures")}
    compat.set_asset_dirs(spec, texturedir=str(tmp_path))
    assert _folders(spec) == {"meshdir": str(tmp_path / "meshes"), "texturedir": str(tmp_path)}


def test_the_xml_holds_a_keyframe_added_after_compiling() -> None:
    spec = mujoco.MjSpec.from_string(ELEMENTS)
    spec.compile()
    spec.add_key(name="start", qpos=[0.5])
    model = mujoco.MjModel.from_xml_string(compat.spec_xml(spec))
    assert model.nkey == 1 and model.key_qpos[0, 0] == 0.5


def test_a_light_is_copied_with_its_kind() -> None:
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><light pos="1 2 3" dir="0 0 -1" directional="true" diffuse="0.3 0.4 0.5"/>'
        '<geom size="0.1"/></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = mujoco.MjvScene(model, maxgeom=10)
    mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, mujoco.MjvCamera(), mujoco.mjtCatBit.mjCAT_ALL, scene)
    source = next(scene.lights[i] for i in range(scene.nlight) if not scene.lights[i].headlight)
    target = mujoco.MjvScene(model, maxgeom=10).lights[0]
    compat.copy_light(source, target)
    np.testing.assert_array_equal(target.pos, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(target.dir, [0.0, 0.0, -1.0])
    np.testing.assert_allclose(target.diffuse, [0.3, 0.4, 0.5], rtol=1e-6)
    kind = "type" if hasattr(source, "type") else "directional"
    assert getattr(target, kind) == getattr(source, kind) and getattr(source, kind)
