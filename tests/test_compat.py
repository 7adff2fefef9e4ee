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


def test_mesh_and_texture_folders_are_set(tmp_path: Path) -> None:
    spec = mujoco.MjSpec()
    compat.set_asset_dirs(spec, meshdir=str(tmp_path / "meshes"), texturedir=str(tmp_path / "textures"))
    text = spec.to_xml() if not compat.mujoco_at_least((3, 3, 1)) else spec.to_xml()
    assert f'meshdir="{tmp_path / "meshes"}"' in text and f'texturedir="{tmp_path / "textures"}"' in text
    compat.set_asset_dirs(spec, texturedir="")
    assert f'meshdir="{tmp_path / "meshes"}"' in spec.to_xml()
