"""Tool families: the pusher's face, the scoop's blades and a scene file's ``[design]`` table."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.generate import generate_dataset, record_trajectory, trajectory_rng
from energy_margin.design.grid import design_grid
from energy_margin.errors import EnergyMarginError
from energy_margin.sim.mujoco_spec import build_model, model_hash
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_file import read_scene_file
from energy_margin.tasks.scene_model import load_scene
from energy_margin.world.state import FrameState

# The default models' hashes before the tool families existed (MuJoCo 4.0.0, 5 objects, friction
# 0.3): the built-in figures rest on these models, so a default must compile to the same bytes.
_DEFAULT_HASHES = {
    ("pushing", False): "374fbd9c2cd0ece6d5d08df4b8e36bcc7ddfe38035677002ae2243b5b4fafa0a",
    ("pushing", True): "b66fe3c690e61810c6fb7b6f8324ffb974183c716e55893bede430e2412ff768",
    ("scooping", False): "3220262bd13fcfc8c57ac9c139b8ab541c0f92ddd77fa8e75a8c766e5e4943af",
}

_DESIGN = '[design]\npusher_width = { geom = "pusher", attribute = "size", index = 0, low = 0.05, high = 0.25 }\n'


def _hash(task: str, config: dict | None = None, n_objects: int = 5, friction: float = 0.3) -> str:
    return model_hash(build_model(get_task(task, config).build_scene(n_objects, friction)))


@pytest.mark.skipif(mujoco.__version__ != "4.0.0", reason="the pinned hashes are MuJoCo 4.0.0's binary models")
@pytest.mark.parametrize(("task", "fast"), sorted(_DEFAULT_HASHES))
def test_default_models_are_unchanged(task: str, fast: bool) -> None:
    config = {"ground_contact": "footprint", "lateral_contact": "sphere"} if fast else None
    assert _hash(task, config) == _DEFAULT_HASHES[(task, fast)]


def test_each_pusher_face_compiles_to_its_own_model() -> None:
    hashes = {face: _hash("pushing", {"pusher_face": face}) for face in ("flat", "v", "arc", "fork")}
    assert len(set(hashes.values())) == 4
    # The same design, the same model; a flat face ignores the hollow's settings.
    assert _hash("pushing", {"pusher_face": "v"}) == hashes["v"]
    assert _hash("pushing", {"face_depth": 0.1, "tine_count": 6}) == hashes["flat"]
    assert _hash("pushing", {"pusher_face": "v", "face_depth": 0.1}) != hashes["v"]
    assert _hash("pushing", {"pusher_face": "fork", "tine_count": 6}) != hashes["fork"]


def _pusher_front(config: dict, x: float) -> float:
    """Where a ray along -y at ``x`` (pusher frame) first meets the pusher, y in the pusher frame."""
    task = get_task("pushing", config)
    model = build_model(task.build_scene(1, 0.3))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pusher = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pusher")
    start = np.array([x, 1.0, data.xpos[pusher][2]])
    geom = np.zeros(1, dtype=np.int32)
    obj = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "object0")
    distance = mujoco.mj_ray(model, data, start, np.array([0.0, -1.0, 0.0]), None, 1, obj, geom)
    assert model.geom_bodyid[geom[0]] == pusher
    return 1.0 - distance


@pytest.mark.parametrize(
    ("face", "middle", "end"),
    [("flat", 0.1, 0.1), ("v", 0.02, 0.1 - 0.08 * 0.005 / 0.4), ("arc", 0.02, None), ("fork", 0.02, 0.1)],
)
def test_face_shapes_put_the_hollow_where_they_say(face: str, middle: float, end: float | None) -> None:
    config = {"pusher_face": face, "face_depth": 0.08}
    assert _pusher_front(config, 0.0) == pytest.approx(middle, abs=1e-6)
    # Near the ends every face reaches the flat face's line (the outer tine sits at the end).
    at_end = _pusher_front(config, 0.395)
    if end is not None:
        assert at_end == pytest.approx(end, abs=2e-3)
    else:
        assert 0.09 < at_end <= 0.1


def test_a_non_flat_face_keeps_the_pushers_mass_and_inertia() -> None:
    def inertial(face: str) -> np.ndarray:
        model = build_model(get_task("pushing", {"pusher_face": face}).build_scene(1, 0.3))
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pusher")
        return np.concatenate([[model.body_mass[body]], model.body_inertia[body], model.body_ipos[body]])

    for face in ("v", "arc", "fork"):
        np.testing.assert_allclose(inertial(face), inertial("flat"))


def _push_one(face: str, engine: str = "mujoco", seconds: float = 1.0) -> tuple[float, float]:
    """Push one cylinder that starts 0.2 m off the pusher's middle; its final x and the pusher's yaw."""
    task = get_task("pushing", {"pusher_face": face, "face_depth": 0.1})
    cfg = task.config
    simulator = task.make_simulator(1, 0.2, engine=engine)
    z = cfg.ground_z + cfg.object_half_height
    simulator.reset(
        FrameState(np.array([[0.2, 0.3, z]]), np.array([[1.0, 0, 0, 0]]), np.zeros((1, 6)), np.zeros(4), np.zeros(4))
    )
    for _ in range(round(seconds / cfg.timestep)):
        simulator.set_robot_force(np.array([0.0, 12.0, 0.0, 0.0]))
        simulator.step(1)
    pusher = simulator.robot_positions()
    return float(simulator.object_positions()[0, 0] - pusher[0]), float(pusher[3])


def test_a_v_face_draws_an_object_towards_its_apex_a_flat_face_does_not() -> None:
    flat_x, _ = _push_one("flat")
    v_x, _ = _push_one("v")
    assert flat_x == pytest.approx(0.2, abs=0.02)  # pushed straight ahead
    assert v_x < flat_x - 0.05  # slid along the V towards the middle


def test_a_non_flat_face_runs_on_pybullet() -> None:
    pytest.importorskip("pybullet")
    x, _ = _push_one("v", engine="pybullet")
    assert np.isfinite(x) and x < 0.17  # the V draws it in on Bullet too


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ({"pusher_face": "round"}, "pusher_face"),
        ({"pusher_face": "v", "face_depth": 0.2}, "face_depth"),
        ({"face_depth": 0.0}, "face_depth"),
        ({"tine_count": 1}, "tine_count"),
        ({"tine_count": 2.5}, "tine_count"),
        ({"pusher_face": "fork", "tine_count": 8, "tine_width": 0.1}, "tine_width"),
        ({"lip_height": -0.001}, "lip_height"),
    ],
)
def test_bad_tool_settings_name_the_setting(config: dict, field: str) -> None:
    task = "scooping" if "lip_height" in config else "pushing"
    with pytest.raises(EnergyMarginError, match=field):
        get_task(task, config)


def test_blade_rims_width_and_length_change_the_scoop() -> None:
    default = _hash("scooping")
    variants = [{"lip_height": 0.004}, {"tip_half_width": 0.03}, {"tip_length": 0.045}, {"scoop_angle": 1.5}]
    hashes = {_hash("scooping", config) for config in variants}
    assert default not in hashes and len(hashes) == len(variants)
    model = build_model(get_task("scooping", {"lip_height": 0.004, "scoop_angle": 1.5707}).build_scene(1, 0.3))
    data = mujoco.MjData(model)
    for joint in ("right_tip", "left_tip"):
        data.qpos[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)]] = 1.5707
    mujoco.mj_kinematics(model, data)

    def geom(name: str) -> np.ndarray:
        return data.geom_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)]

    for side in ("right", "left"):
        blade, rims = geom(f"{side}_tip"), [geom(f"{side}_tip_lip{i}") for i in (0, 1)]
        # Horizontal blades: the rims stand on the upper face, along the two long edges.
        for rim, edge in zip(rims, (1.0, -1.0), strict=True):
            assert rim[2] == pytest.approx(blade[2] + 0.0005 + 0.002, abs=1e-6)
            assert rim[1] == pytest.approx(edge * (0.02 - 0.0005), abs=1e-6)
    flat = build_model(get_task("scooping").build_scene(1, 0.3))
    assert mujoco.mj_name2id(flat, mujoco.mjtObj.mjOBJ_GEOM, "right_tip_lip0") < 0  # no rims by default


@pytest.mark.parametrize("task", ["pushing", "scooping"])
def test_design_space_corners_are_valid_compile_and_roll_out(task: str) -> None:
    space = get_task(task).design_space()
    assert space
    params = [(p.name, list(p.choices) if p.choices is not None else [p.low, p.high]) for p in space]
    designs = design_grid(get_task(task), params)
    assert len(designs) == int(np.prod([len(values) for _, values in params]))
    hashes = set()
    for index, design in enumerate(designs):
        built = get_task(task, design.overrides)
        hashes.add(built.model_sha256(3))
        if index % 5 == 0:  # a roll-out of every fifth corner keeps the test short
            record = record_trajectory(built, 3, 2, trajectory_rng(0, 1, 0))
            assert np.all(np.isfinite(record["object_pos"]))
    # Corners differ in their model, except a flat face's unused hollow and tine settings.
    assert len(hashes) > len(designs) // 2


def test_dataset_records_the_models_hash(tmp_path: Path) -> None:
    def hash_of(config: dict, name: str) -> str:
        generate_dataset(
            "pushing", out=tmp_path / name, n_trajectories=1, n_frames=2, n_objects=2, seed=0, task_config=config
        )
        return json.loads((tmp_path / name / "dataset.json").read_text())["model_sha256"]

    v = hash_of({"pusher_face": "v"}, "v")
    assert hash_of({"pusher_face": "v"}, "v_again") == v == get_task("pushing", {"pusher_face": "v"}).model_sha256(2)
    assert hash_of({}, "flat") != v


# -- scene files ---------------------------------------------------------------------------


def test_scene_design_parameter_sets_the_model_and_its_hash(make_scene) -> None:
    path = make_scene(append=_DESIGN)
    (entry,) = read_scene_file(path).design
    assert (entry.name, entry.kind, entry.element, entry.attribute, entry.index) == (
        "pusher_width",
        "geom",
        "pusher",
        "size",
        0,
    )
    default = get_task("scene", {"scene_file": str(path)})
    assert default.config.pusher_width == pytest.approx(0.15)  # the model's own value
    assert default.loaded.model_sha256 == load_scene(make_scene()).model_sha256  # applying it changes nothing
    wide = get_task("scene", {"scene_file": str(path), "pusher_width": 0.2})
    geom = mujoco.mj_name2id(wide.loaded.model, mujoco.mjtObj.mjOBJ_GEOM, "pusher")
    assert wide.loaded.model.geom_size[geom, 0] == pytest.approx(0.2)
    assert wide.loaded.model_sha256 != default.loaded.model_sha256
    assert wide.model_sha256(2) == wide.loaded.model_sha256
    # The recorded configuration rebuilds the same design (its hash is checked).
    again = get_task("scene", wide.config.to_dict())
    assert again.loaded.model_sha256 == wide.loaded.model_sha256
    (parameter,) = wide.design_space()
    assert (parameter.name, parameter.low, parameter.high) == ("pusher_width", 0.05, 0.25)
    assert "size[0] of geom 'pusher'" in parameter.doc
    # A default in the file is the value without an override.
    with_default = make_scene(append=_DESIGN.replace("high = 0.25", "high = 0.25, default = 0.1"))
    assert get_task("scene", {"scene_file": str(with_default)}).config.pusher_width == pytest.approx(0.1)


def test_scene_design_sweeps_as_a_setting(make_scene) -> None:
    path = make_scene(append=_DESIGN)
    designs = design_grid(
        get_task("scene", {"scene_file": str(path)}), [("pusher_width", [0.1, 0.2])], fixed={"scene_file": str(path)}
    )
    hashes = {get_task("scene", design.overrides).loaded.model_sha256 for design in designs}
    assert len(hashes) == 2


def test_scene_design_sets_a_bodys_mass(make_scene) -> None:
    # MuJoCo ignores a body's mass unless its inertial is explicit: the design makes it so, from the
    # compiled model, and the model's own value is the compiled mass (the MJCF gives it on the geom).
    path = make_scene(append='[design]\nbox_mass = { body = "box_a", attribute = "mass", low = 0.05, high = 0.5 }\n')

    def model(mass: float | None) -> tuple[mujoco.MjModel, str]:
        task = get_task("scene", {"scene_file": str(path), **({} if mass is None else {"box_mass": mass})})
        return task.loaded.model, task.loaded.model_sha256

    default, _ = model(None)
    body = mujoco.mj_name2id(default, mujoco.mjtObj.mjOBJ_BODY, "box_a")
    assert get_task("scene", {"scene_file": str(path)}).config.box_mass == pytest.approx(0.1)
    light, light_hash = model(0.2)
    heavy, heavy_hash = model(0.3)
    assert (light.body_mass[body], heavy.body_mass[body]) == pytest.approx((0.2, 0.3))
    assert light_hash != heavy_hash
    # Only the mass changes: the inertia and centre of mass stay the compiled model's.
    for changed in (light, heavy):
        assert changed.body_inertia[body] == pytest.approx(default.body_inertia[body])
        assert changed.body_ipos[body] == pytest.approx(default.body_ipos[body])
    # A model that derives every inertial from its geoms cannot take one: refused in one line.
    derived = make_scene(
        append='[design]\nbox_mass = { body = "box_a", attribute = "mass", low = 0.05, high = 0.5 }\n',
        model_replace={"<default>": '<compiler inertiafromgeom="true"/><default>'},
    )
    with pytest.raises(EnergyMarginError, match=r"design\.box_mass\.attribute: mass of body 'box_a' cannot be set"):
        load_scene(derived)


@pytest.mark.parametrize(
    ("design", "fragment"),
    [
        ('w = { geom = "paddle", attribute = "size", index = 0, low = 0.05, high = 0.2 }', "no geom 'paddle'"),
        ('w = { geom = "pusher", attribute = "sise", index = 0, low = 0.05, high = 0.2 }', "no attribute 'sise'"),
        ('w = { geom = "pusher", attribute = "size", index = 3, low = 0.05, high = 0.2 }', "index 3 is out of range"),
        ('w = { geom = "pusher", attribute = "size", low = 0.05, high = 0.2 }', "holds 3 numbers: give index"),
        ('w = { geom = "pusher", attribute = "name", low = 0.05, high = 0.2 }', "not a real number"),
        ('w = { geom = "pusher", attribute = "size", index = 0, low = 0.2, high = 0.05 }', "is inverted"),
        ('w = { geom = "pusher", attribute = "size", index = 0, low = 0.2, high = 0.2 }', "is empty"),
        ('w = { geom = "pusher", attribute = "size", index = 0, low = 0.2, high = 0.3 }', "lies outside its range"),
        ('w = { geom = "pusher", attribute = "size", index = 0, low = 0, high = 1, default = 2 }', "outside the range"),
        ('w = { geom = "pusher", body = "pusher", attribute = "size", low = 0, high = 1 }', "give only one of"),
        ('w = { attribute = "size", low = 0, high = 1 }', "needs one of body, geom"),
        ('w = { geom = "pusher", attribute = "size", index = 0, low = 0 }', "needs low and high"),
        ('duration = { body = "pusher", attribute = "mass", low = 0, high = 1 }', "a setting of the scene task"),
        ('w = { geom = "pusher", attribute = "size", index = 0, low = 0, high = 1, colour = 1 }', "unknown key"),
    ],
)
def test_bad_design_tables_are_one_line_naming_the_line(make_scene, design: str, fragment: str) -> None:
    path = make_scene(append=f"\n[design]\n{design}\n")
    line = len(path.read_text().splitlines())
    with pytest.raises(EnergyMarginError) as error:
        load_scene(path)
    message = str(error.value)
    assert fragment in message and "\n" not in message
    assert message.startswith(f"{path}:{line}: design.")


def test_scene_design_values_outside_their_range_or_unknown(make_scene) -> None:
    path = make_scene(append=_DESIGN)
    with pytest.raises(EnergyMarginError, match=r"pusher_width = 0.5 \(given\) lies outside its range"):
        get_task("scene", {"scene_file": str(path), "pusher_width": 0.5})
    with pytest.raises(EnergyMarginError, match=r"unknown scene configuration keys: paddle .*pusher_width"):
        get_task("scene", {"scene_file": str(path), "paddle": 0.1})


def test_generate_sets_a_scene_design_with_set(make_scene, tmp_path: Path, capsys) -> None:
    path = make_scene(append=_DESIGN)
    hashes = []
    for width in ("0.1", "0.2"):
        out = tmp_path / f"w{width}"
        command = ["generate", "--scene", str(path), "--set", f"pusher_width={width}", "--trajectories", "1"]
        assert main([*command, "--frames", "2", "--out", str(out)]) == 0
        metadata = json.loads((out / "dataset.json").read_text())
        assert metadata["task_config"]["pusher_width"] == float(width)
        assert metadata["model_sha256"] == metadata["task_config"]["model_sha256"]
        hashes.append(metadata["model_sha256"])
    assert hashes[0] != hashes[1]
    out = tmp_path / "other"
    assert main(["generate", "--scene", str(path), "--set", "timestep=0.1", "--out", str(out)]) == 2
    assert "except for its [design] parameters (pusher_width)" in capsys.readouterr().err
