"""Scene files: parsing, the task built from one, and every bad input as one line naming file and key."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import tiny_scene
from energy_margin.cli import main
from energy_margin.errors import EnergyMarginError, InvalidDataError, InvalidParameterError
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_file import DEFAULTED_KEYS, Locator, read_scene_file
from energy_margin.tasks.scene_model import load_scene


def test_tiny_scene_parses_and_builds_a_task(tiny_scene: Path) -> None:
    spec = read_scene_file(tiny_scene)
    assert spec.bodies == ("box_*",)
    assert spec.motion.duration == 1.5
    assert spec.friction_range == (0.3, 0.6)
    loaded = load_scene(tiny_scene)
    assert loaded.object_names == ("box_a", "box_b")
    assert loaded.robot_joints == ()
    np.testing.assert_allclose(loaded.model.body_mass[loaded.object_bodies], [0.1, 0.1])
    task = get_task("scene", {"scene_file": str(tiny_scene)})
    assert task.fixed_objects == 2
    assert task.robot_dofs() == 7  # one mocap body: position and quaternion
    # The mocap pusher follows the keyframes linearly, at the trajectory's time scale.
    command = task.model_command(np.array([1.0, 1.0]), 0.5)
    assert command is not None and command.mocap_pos is not None
    np.testing.assert_allclose(command.mocap_pos, [[0.0, 0.0, 0.03]], atol=1e-12)
    command = task.model_command(np.array([2.0, 1.0]), 0.5)
    assert command is not None and command.mocap_pos is not None
    np.testing.assert_allclose(command.mocap_pos, [[0.0, 0.15, 0.03]])
    # Randomised starts never overlap and respect the ranges.
    trajectory = task.sample_trajectory(np.random.default_rng(3), 2)
    pos = trajectory.initial.object_pos
    assert np.all((pos[:, 0] >= -0.12) & (pos[:, 0] <= 0.12))
    # Apart in x-y by twice the boxes' footprint radius (their x-y corner, 0.03 sqrt(2) m).
    assert np.linalg.norm(pos[0, :2] - pos[1, :2]) > 2 * 0.03 * np.sqrt(2)
    assert 0.3 <= trajectory.friction <= 0.6


def test_capture_region_follows_the_pusher_of_the_frame(tiny_scene: Path) -> None:
    task = get_task("scene", {"scene_file": str(tiny_scene)})
    trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
    frame = trajectory.initial
    # Pusher at y = -0.15: the box covers y in [-0.13, 0.07] in front of it.
    region = task.capture_region(frame)
    assert region.contains(np.array([[0.0, -0.1, 0.03], [0.0, 0.2, 0.03]])).tolist() == [True, False]
    moved_q = frame.robot_q.copy()
    moved_q[1] = 0.15
    moved = type(frame)(frame.object_pos, frame.object_quat, frame.object_vel, moved_q, frame.robot_v)
    region = task.capture_region(moved)
    assert region.contains(np.array([[0.0, -0.1, 0.03], [0.0, 0.2, 0.03]])).tolist() == [False, True]


def test_locator_finds_keys_in_tables_and_arrays_of_tables(tiny_scene: Path) -> None:
    text = tiny_scene.read_text()
    lines = text.splitlines()
    locator = Locator(text)
    line = locator.line("motion.keyframes[1].mocap.pusher.pos")
    assert line is not None and lines[line - 1].startswith("mocap.pusher.pos = [0.0, 0.3")
    line = locator.line("capture.region.of[0].type")
    assert line is not None and lines[line - 1].startswith("region = ")
    line = locator.line("randomize.start.yaw")
    assert line is not None and lines[line - 1].startswith("yaw =")


BAD_INPUTS = [
    # (scene replacements, model replacements, expected key, expected fragment)
    ({'mjcf = "model.xml"': 'mjcf = "missing.xml"'}, {}, ":2: mjcf:", "missing.xml does not exist"),
    ({}, {'type="plane"': 'type="planar"'}, ":2: mjcf:", "model.xml cannot be loaded"),
    (
        {},
        {'mass="0.1"/></body>\n    <body name="box_b"': 'mass="-1"/></body>\n    <body name="box_b"'},
        ":2: mjcf:",
        "does not compile",
    ),
    ({'bodies = ["box_*"]': 'bodies = ["box_a", "crate"]'}, {}, ":5: objects.bodies:", "no body 'crate'"),
    (
        {},
        {'"box_b" pos="0.06 0 0.03"><freejoint/>': '"box_b" pos="0.06 0 0.03"><joint type="hinge"/>'},
        "objects.joints:",
        "'box_b' in model.xml is not free",
    ),
    (
        {"mocap.pusher.pos = [0.0, 0.3, 0.03]": "mocap.pusher.pos = [0.0, 0.3, 0.03]\nctrl = [1.0]"},
        {},
        ":10: motion.keyframes[0]:",
        "has no ctrl",
    ),
    (
        {
            "mocap.pusher.pos = [0.0, -0.15, 0.03]": "mocap.pusher.pos = [0.0, -0.15, 0.03]\nctrl = [1.0]",
            "mocap.pusher.pos = [0.0, 0.3, 0.03]": "mocap.pusher.pos = [0.0, 0.3, 0.03]\nctrl = [1.0]",
        },
        {},
        "motion.keyframes[0].ctrl:",
        "has 1 values for the 0 actuators",
    ),
    (
        {"duration = 1.5\n": 'duration = 1.5\nactuators = ["gripper"]\n'},
        {},
        "motion.actuators:",
        "no actuator 'gripper'",
    ),
    ({'site = "goal"': 'site = "target"'}, {}, "success.region.of[0].site:", "no site 'target'"),
    ({'body = "pusher", center': 'body = "arm", center'}, {}, "capture.region.body:", "no body 'arm'"),
    (
        {
            "mocap.pusher.pos = [0.0, -0.15": "mocap.box_a.pos = [0.0, -0.15",
            "mocap.pusher.pos = [0.0, 0.3": "mocap.box_a.pos = [0.0, 0.3",
        },
        {},
        "motion.keyframes[0].mocap.box_a:",
        "is not a mocap body",
    ),
    ({'type = "box", body': 'type = "sphere", body'}, {}, "capture.region.type:", "unknown region type 'sphere'"),
    (
        {"half_size = [0.2, 0.1, 0.1] }": "half_size = [0.2, 0.1, 0.1], radius = 2.0 }"},
        {},
        "capture.region.radius:",
        "unknown key",
    ),
    ({"[randomize]\n": "[randomize]\ncolour = 1\n"}, {}, "randomize.colour:", "unknown key"),
    ({"[capture]\n": "[capture]\nfollow = 1\n"}, {}, "capture.follow:", "must be true or false"),
    ({"[success]\n": "[success]\nfollow = 1\n"}, {}, "success.follow:", "must be true or false"),
    ({"[success]\n": '[success]\nfollow = "yes"\n'}, {}, "success.follow:", "must be true or false"),
    ({"x = [-0.12, 0.12]\ny = [-0.02, 0.08]": "x = [0.0, 0.0]\ny = [0.0, 0.0]"}, {}, "randomize.start", "cannot place"),
    ({"schema_version = 1": "schema_version = 7"}, {}, ":1: schema_version:", "not supported"),
    ({"time = 1.5\n": "time = 0.0\n"}, {}, "motion.keyframes[1].time:", "must increase"),
    ({"max_duration = 0.1": "max_duration = -0.1"}, {}, "perturbation.max_duration:", "must be > 0"),
    # Found by fuzzing (tests/tasks/test_fuzz_scene_file.py): each escaped as another exception or was accepted.
    ({"schema_version = 1": "schema_version = true"}, {}, ":1: schema_version:", "True is not supported"),
    ({'mjcf = "model.xml"': 'mjcf = "model\\u0000.xml"'}, {}, ":2: mjcf:", "without NUL characters"),
    ({'mjcf = "model.xml"': 'mjcf = "' + "m" * 300 + '.xml"'}, {}, ":2: mjcf:", "cannot be read"),
    ({'mjcf = "model.xml"': 'mjcf = "."'}, {}, ":2: mjcf:", "is not a file"),
    (
        {'type = "box", body = "pusher"': 'type = ["box"], body = "pusher"'},
        {},
        "capture.region.type:",
        "unknown region",
    ),
    ({"[objects]\n": "[objects]\n" + "x = " + "[" * 70 + "]" * 70 + "\n"}, {}, "", "nested more than 64 levels"),
    ({"[objects]\n": "[objects]\n" + "x = " + "[" * 5000 + "]" * 5000 + "\n"}, {}, "", "nested too deeply"),
]


@pytest.mark.parametrize(("replace", "model_replace", "key", "fragment"), BAD_INPUTS)
def test_bad_scene_inputs_are_one_line_naming_file_and_key(
    make_scene, tmp_path: Path, capsys: pytest.CaptureFixture[str], replace, model_replace, key, fragment
) -> None:
    scene = make_scene(replace=replace, model_replace=model_replace)
    out = tmp_path / "out"
    status = main(["generate", "--scene", str(scene), "--trajectories", "2", "--frames", "2", "--out", str(out)])
    error = capsys.readouterr().err
    assert status == 2
    assert error.count("\n") == 1 and "Traceback" not in error
    assert str(scene) in error, error
    assert key in error, error
    assert fragment in error, error
    assert not out.exists()
    assert not any(path.name.startswith(".") for path in tmp_path.iterdir())


def test_pybullet_with_a_scene_file_is_one_line(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    status = main(["generate", "--scene", str(tiny_scene), "--engine", "pybullet", "--out", str(out)])
    error = capsys.readouterr().err
    assert status == 2 and error.count("\n") == 1
    assert f"scene file {tiny_scene} runs on mujoco only, not --engine pybullet" in error
    assert not out.exists()


def test_wrong_object_count_and_missing_scene_file(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["generate", "--scene", str(tiny_scene), "--objects", "3", "--out", str(out)]) == 2
    assert "has 2 objects; --objects 3 differs" in capsys.readouterr().err
    assert main(["generate", "--scene", str(tmp_path / "nope.toml"), "--out", str(out)]) == 2
    assert "nope.toml: scene file does not exist" in capsys.readouterr().err
    assert not out.exists()


def test_template_copies_are_added_without_overlap(make_scene) -> None:
    box_b = (
        '<body name="box_b" pos="0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>'
    )
    scene = make_scene(replace={'bodies = ["box_*"]': 'template = "box_a"\ncount = 4'}, model_replace={box_b: ""})
    loaded = load_scene(scene)
    assert loaded.object_names == ("box_a_0", "box_a_1", "box_a_2", "box_a_3")
    start = loaded.model.qpos0[[loaded.model.jnt_qposadr[j] for j in loaded.object_joints]]
    assert len(set(np.round(start, 6))) == 4
    task = get_task("scene", {"scene_file": str(scene)})
    assert task.fixed_objects == 4


@pytest.mark.parametrize(
    ("objects", "fragment"),
    [
        ('template = "world"\ncount = 2', "objects.template: body 'world' must be a child of the worldbody"),
        ('template = "box_a"\ncount = 1001', "objects.count: must be at most 1000, got 1001"),
    ],
)
def test_template_that_cannot_be_copied_is_one_line(make_scene, objects: str, fragment: str) -> None:
    scene = make_scene(replace={'bodies = ["box_*"]': objects})
    with pytest.raises(EnergyMarginError, match=re.escape(fragment)) as error:
        load_scene(scene)
    assert "\n" not in str(error.value)


ROBOT_MODEL_EDIT = {
    '<body name="box_a"': '<body name="slider" pos="0 -0.5 0.03"><joint name="slide" type="slide" axis="1 0 0"/>'
    '<geom type="box" size="0.02 0.02 0.02" mass="1"/></body>\n    <body name="box_a"',
    "</worldbody>": '</worldbody>\n  <actuator><position name="servo" joint="slide" kp="50"/></actuator>',
}


def test_control_keyframes_interpolate_linearly_or_hold(make_scene) -> None:
    keyframes = "\n[[motion.keyframes]]\ntime = 0.0\nctrl = [0.0]\n[[motion.keyframes]]\ntime = 1.0\nctrl = [0.4]\n"
    base = {"[[motion.keyframes]]\ntime = 0.0\nmocap.pusher.pos = [0.0, -0.15, 0.03]\n\n": ""}
    base["[[motion.keyframes]]\ntime = 1.5\nmocap.pusher.pos = [0.0, 0.3, 0.03]\n"] = keyframes
    linear = get_task("scene", {"scene_file": str(make_scene(replace=base, model_replace=ROBOT_MODEL_EDIT))})
    command = linear.model_command(np.ones(2), 0.25)
    assert command is not None and command.ctrl is not None and command.mocap_pos is None
    np.testing.assert_allclose(command.ctrl, [0.1])
    assert linear.robot_dofs() == 1 + 7  # the slide joint, then the (unmoved) mocap pusher
    hold = dict(base)
    hold["duration = 1.5\n"] = 'duration = 1.5\ninterpolation = "hold"\n'
    held = get_task("scene", {"scene_file": str(make_scene(replace=hold, model_replace=ROBOT_MODEL_EDIT))})
    command = held.model_command(np.ones(2), 0.99)
    assert command is not None and command.ctrl is not None
    np.testing.assert_allclose(command.ctrl, [0.0])
    after = held.model_command(np.ones(2), 1.2)
    assert after is not None and after.ctrl is not None
    np.testing.assert_allclose(after.ctrl, [0.4])


def _mocap_quat_midpoint(make_scene, first: list[float], second: list[float]) -> np.ndarray:
    """The pusher's interpolated quaternion halfway between keyframes with quaternions ``first`` and ``second``."""
    replace = {
        line: f"{line}mocap.pusher.quat = {quat}\n"
        for line, quat in (
            ("mocap.pusher.pos = [0.0, -0.15, 0.03]\n", first),
            ("mocap.pusher.pos = [0.0, 0.3, 0.03]\n", second),
        )
    }
    motion = load_scene(make_scene(replace=replace)).motion
    poses = motion.mocap_at(0.75)
    assert poses is not None
    return poses[1][0]


def test_opposite_keyframe_quaternions_are_one_orientation(make_scene) -> None:
    # q and -q are the same orientation: halfway between them is that orientation, not NaN.
    q = np.array([0.5, 0.5, -0.5, 0.5])
    for other in (-q, q):
        halfway = _mocap_quat_midpoint(make_scene, q.tolist(), other.tolist())
        assert np.all(np.isfinite(halfway))
        np.testing.assert_allclose(abs(float(np.dot(halfway, q))), 1.0, rtol=0, atol=1e-12)


def test_keyframe_quaternions_follow_the_shortest_arc(make_scene) -> None:
    # 0 and 120 degrees about z: halfway is 60 degrees (slerp), whichever sign the second has.
    def about_z(degrees: float) -> np.ndarray:
        half = np.radians(degrees) / 2
        return np.array([np.cos(half), 0.0, 0.0, np.sin(half)])

    for sign in (1.0, -1.0):
        halfway = _mocap_quat_midpoint(make_scene, about_z(0).tolist(), (sign * about_z(120)).tolist())
        np.testing.assert_allclose(halfway, about_z(60), rtol=0, atol=1e-12)
    # Past 180 degrees the shorter way round is the other direction: 0 and 300 give -30.
    halfway = _mocap_quat_midpoint(make_scene, about_z(0).tolist(), about_z(300).tolist())
    np.testing.assert_allclose(halfway * np.sign(halfway[0]), about_z(-30), rtol=0, atol=1e-12)


def test_control_file_and_its_errors(make_scene, tmp_path: Path) -> None:
    replace = {
        "[[motion.keyframes]]\ntime = 0.0\nmocap.pusher.pos = [0.0, -0.15, 0.03]\n\n": "",
        "[[motion.keyframes]]\ntime = 1.5\nmocap.pusher.pos = [0.0, 0.3, 0.03]\n": "",
        "duration = 1.5\n": 'duration = 1.5\nctrl_file = "ctrl.npz"\n',
    }
    scene = make_scene(replace=replace, model_replace=ROBOT_MODEL_EDIT)
    np.savez(scene.parent / "ctrl.npz", time=np.array([0.0, 1.0]), ctrl=np.array([[0.0], [0.2]]))
    task = get_task("scene", {"scene_file": str(scene)})
    command = task.model_command(np.array([2.0, 1.0]), 0.25)  # time scale 2: the file's t = 0.5
    assert command is not None and command.ctrl is not None
    np.testing.assert_allclose(command.ctrl, [0.1])
    np.savez(scene.parent / "ctrl.npz", time=np.array([0.0, 0.0]), ctrl=np.array([[0.0], [0.2]]))
    with pytest.raises(Exception, match=r"motion.ctrl_file: ctrl.npz: time is not increasing \(row 1\)"):
        load_scene(scene)
    np.savez(scene.parent / "ctrl.npz", time=np.array([0.0, 1.0]), ctrl=np.zeros((2, 3)))
    with pytest.raises(Exception, match=r"ctrl has shape \(2, 3\), expected \(2, 1\)"):
        load_scene(scene)


def test_a_pile_start_has_no_overlap(make_scene) -> None:
    start = "[randomize.start]\nx = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n"
    pile = '[randomize.start]\nmode = "pile"\nlow = [-0.1, 0.1, 0.05]\nhigh = [0.1, 0.3, 0.2]\n'
    task = get_task("scene", {"scene_file": str(make_scene(replace={start: pile}))})
    for seed in range(5):
        initial = task.sample_trajectory(np.random.default_rng(seed), 2).initial
        assert np.all(initial.object_pos >= [-0.1, 0.1, 0.05]) and np.all(initial.object_pos <= [0.1, 0.3, 0.2])
        assert np.linalg.norm(initial.object_pos[0] - initial.object_pos[1]) > 0.1
        np.testing.assert_allclose(np.linalg.norm(initial.object_quat, axis=1), 1.0)


def test_scene_file_takes_no_set_overrides(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["generate", "--scene", str(tiny_scene), "--set", "timestep=0.1", "--out", str(out)]) == 2
    assert "--set does not apply to --scene" in capsys.readouterr().err
    assert not out.exists()


def test_contact_region_uses_each_objects_orientation(make_scene) -> None:
    # Success: every box touches the ground (within 1 mm), taken from the model.
    success = 'region = { type = "contact", geom = "ground", margin = 0.001 }'
    old = """region = { type = "all", of = [
  { type = "distance", site = "goal", max = 0.16 },
  { type = "height", max = 0.1 },
] }"""
    task = get_task("scene", {"scene_file": str(make_scene(replace={old: success}))})
    region = task.success_region()
    assert getattr(region, "uses_orientation", False)
    upright = np.array([1.0, 0.0, 0.0, 0.0])
    tilted = np.array([np.cos(np.pi / 8), np.sin(np.pi / 8), 0.0, 0.0])  # 45 degrees about x
    positions = np.array([[[0.0, 0.0, 0.03], [0.3, 0.0, 0.04]], [[0.0, 0.0, 0.0305], [0.3, 0.0, 0.04]]])
    # A 3 cm half-edge box resting at z = 0.03 touches; upright at z = 0.04 it is 1 cm above.
    quats = np.array([[upright, upright], [upright, tilted]])
    inside = region.contains(positions, None, quaternions=quats)
    assert inside.tolist() == [[True, False], [True, True]]  # tilted 45 degrees its edge reaches down 4.24 cm
    # Frames label with the objects' own orientations.
    trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
    assert task.is_successful(trajectory.initial)  # both boxes start resting on the ground
    frame = trajectory.initial
    lifted = type(frame)(
        frame.object_pos + np.array([0.0, 0.0, 0.01]), frame.object_quat, frame.object_vel, frame.robot_q, frame.robot_v
    )
    assert not task.is_successful(lifted)
    np.testing.assert_allclose(region.signed_distance(np.array([[0.0, 0.0, 0.05]])), [0.001 - 0.02], atol=1e-9)
    # The analysis scores the tree's states with their orientations: resting boxes stay in contact.
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame

    config = AnalyzerConfig(expansions=10)
    scores, field = analyze_frame(task, frame, friction=0.5, drive=trajectory.drive, seed=0, config=config)
    assert field.object_quat.shape == (field.nodes, 2, 4)
    assert 0.5 < scores.success_score <= 1.0


def test_contact_with_an_unknown_geom_is_one_line(make_scene, tmp_path: Path, capsys) -> None:
    old = 'region = { type = "box", body = "pusher", center = [0.0, 0.12, 0.0], half_size = [0.2, 0.1, 0.1] }'
    scene = make_scene(replace={old: 'region = { type = "contact", geom = "floor" }'})
    out = tmp_path / "out"
    assert main(["generate", "--scene", str(scene), "--trajectories", "1", "--frames", "2", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "capture.region.geom: no geom 'floor' in model.xml" in error and error.count("\n") == 1
    assert not out.exists()


def test_success_region_in_a_moving_body_frame_is_taken_at_the_frame(make_scene) -> None:
    # Success: every box inside a box carried by the pusher (a tray), taken where the frame has it.
    tray = 'region = { type = "box", body = "pusher", center = [0.0, 0.12, 0.0], half_size = [0.2, 0.1, 0.1] }'
    old = """region = { type = "all", of = [
  { type = "distance", site = "goal", max = 0.16 },
  { type = "height", max = 0.1 },
] }"""
    task = get_task("scene", {"scene_file": str(make_scene(replace={old: tray}))})
    frame = task.sample_trajectory(np.random.default_rng(0), 2).initial
    points = np.array([[0.0, -0.1, 0.03], [0.0, 0.2, 0.03]])
    assert task.success_region_at(frame).contains(points).tolist() == [True, False]
    moved_q = frame.robot_q.copy()
    moved_q[1] = 0.15
    moved = type(frame)(frame.object_pos, frame.object_quat, frame.object_vel, moved_q, frame.robot_v)
    assert task.success_region_at(moved).contains(points).tolist() == [False, True]
    # Labels use the frame's own tray pose.
    boxes_ahead = type(frame)(
        np.array([[0.0, 0.2, 0.03], [0.05, 0.22, 0.03]]), frame.object_quat, frame.object_vel, moved_q, frame.robot_v
    )
    assert task.is_successful(boxes_ahead)
    assert not task.is_successful(
        type(frame)(boxes_ahead.object_pos, frame.object_quat, frame.object_vel, frame.robot_q, frame.robot_v)
    )


# A hinge arm driven by a position servo, and a puck on two slides (y declared before x, as in
# Gymnasium's Pusher) whose body sits away from the origin.
# The arm and a puck beyond its reach at (0.4, 0.1); ROBOT is replaced by the motion's robot line.
ARM_AND_PUCK = tiny_scene.ARM_AND_PUCK.format(x=0.4, y=0.1)
ARM_AND_PUCK_SCENE = tiny_scene.ARM_AND_PUCK_SCENE.replace("DURATION", "1.0")


def test_a_puck_on_two_slides_is_an_upright_object_at_its_world_position(tmp_path: Path) -> None:
    from tiny_scene import write_tiny_scene

    scene = write_tiny_scene(tmp_path, scene=ARM_AND_PUCK_SCENE.replace("ROBOT", ""), model=ARM_AND_PUCK)
    task = get_task("scene", {"scene_file": str(scene)})
    simulator = task.make_simulator(1, task.default_friction(), np.ones(2))
    frame = simulator.frame_state()
    np.testing.assert_allclose(frame.object_pos, [[0.4, 0.1, 0.03]])
    moved = type(frame)(
        np.array([[0.5, -0.2, 0.03]]), frame.object_quat, frame.object_vel, frame.robot_q, frame.robot_v
    )
    simulator.reset(moved)
    assert np.allclose(simulator.data.xpos[task.loaded.object_bodies[0]], [0.5, -0.2, 0.03])
    np.testing.assert_allclose(simulator.frame_state().object_pos, [[0.5, -0.2, 0.03]])
    # z, which has no joint, stays where the body puts it.
    high = type(frame)(np.array([[0.5, -0.2, 0.3]]), frame.object_quat, frame.object_vel, frame.robot_q, frame.robot_v)
    simulator.reset(high)
    assert simulator.frame_state().object_pos[0, 2] == pytest.approx(0.03)


@pytest.mark.parametrize(("robot", "moves"), [("", True), ('robot = "still"', False)])
def test_motion_robot_still_holds_the_robot_where_the_frame_has_it(tmp_path: Path, robot: str, moves: bool) -> None:
    from tiny_scene import write_tiny_scene

    scene = write_tiny_scene(tmp_path, scene=ARM_AND_PUCK_SCENE.replace("ROBOT", robot), model=ARM_AND_PUCK)
    task = get_task("scene", {"scene_file": str(scene)})
    simulator = task.make_simulator(1, task.default_friction(), np.ones(2))
    frame = simulator.frame_state()
    turning = type(frame)(frame.object_pos, frame.object_quat, frame.object_vel, np.array([0.5]), np.array([2.0]))
    simulator.reset(turning)
    travelled = 0.0
    for _ in range(30):
        simulator.step(1)
        travelled = max(travelled, abs(float(simulator.robot_positions()[0]) - 0.5))
    assert (travelled > 0.05) if moves else (travelled < 1e-6)


@pytest.mark.parametrize("robot", ["coasting", "still"])
def test_motion_robot_coasting_keeps_the_frames_velocity_and_pushes_what_it_meets(tmp_path: Path, robot: str) -> None:
    """A coasting arm turns on at the frame's 2 rad/s against its servo and the puck it meets; a still one stays."""
    from tiny_scene import write_tiny_scene

    text = ARM_AND_PUCK_SCENE.replace("ROBOT", f'robot = "{robot}"')
    scene = write_tiny_scene(tmp_path, scene=text, model=ARM_AND_PUCK)
    task = get_task("scene", {"scene_file": str(scene)})
    simulator = task.make_simulator(1, task.default_friction(), np.ones(2))
    assert simulator.coasting == (robot == "coasting") and simulator.still == (robot == "still")
    frame = simulator.frame_state()
    # The puck inside the arm's sweep, 0.46 rad ahead of it; the arm turning towards it.
    puck = np.array([[0.2, 0.1, 0.03]])
    simulator.reset(type(frame)(puck, frame.object_quat, frame.object_vel, np.array([0.0]), np.array([2.0])))
    simulator.step(40)  # 0.4 s
    angle, speed = float(simulator.robot_positions()[0]), float(simulator.robot_velocities()[0])
    pushed = float(np.linalg.norm(simulator.frame_state().object_pos[0, :2] - puck[0, :2]))
    if robot == "coasting":
        assert angle == pytest.approx(0.8, abs=1e-3)
        assert speed == pytest.approx(2.0, abs=1e-4)
        assert pushed > 0.02
    else:
        assert abs(angle) < 1e-6 and abs(speed) < 1e-6
        assert pushed < 1e-6


@pytest.mark.parametrize(("robot", "armature"), [("still", 1e8), ("coasting", 1e6), ("declared", None)])
def test_a_held_robot_is_heavier_than_a_coasting_one(tmp_path: Path, robot: str, armature: float | None) -> None:
    """A still robot's joints get STILL_ARMATURE, a coasting (moving) one's the hundredth COASTING_ARMATURE."""
    from energy_margin.sim.mujoco_model import COASTING_ARMATURE, STILL_ARMATURE
    from tiny_scene import write_tiny_scene

    assert (STILL_ARMATURE, COASTING_ARMATURE) == (1e8, 1e6)
    scene = write_tiny_scene(tmp_path, scene=ARM_AND_PUCK_SCENE.replace("ROBOT", f'robot = "{robot}"'),
                             model=ARM_AND_PUCK)  # fmt: skip
    task = get_task("scene", {"scene_file": str(scene)})
    simulator = task.make_simulator(1, task.default_friction(), np.ones(2))
    robot_dofs = simulator.index.robot_qvel
    expected = task.loaded.model.dof_armature[robot_dofs] if armature is None else armature
    np.testing.assert_array_equal(simulator.model.dof_armature[robot_dofs], expected)


def test_a_robot_both_still_and_coasting_is_refused(tmp_path: Path) -> None:
    from energy_margin.sim import make_model_simulator
    from tiny_scene import write_tiny_scene

    scene = write_tiny_scene(tmp_path, scene=ARM_AND_PUCK_SCENE.replace("ROBOT", ""), model=ARM_AND_PUCK)
    task = get_task("scene", {"scene_file": str(scene)})
    loaded = task.loaded
    with pytest.raises(InvalidParameterError, match=r"^coasting cannot be combined with still"):
        make_model_simulator(
            task.compiled_model(task.default_friction()),
            task.build_scene(1, task.default_friction()),
            object_joints=list(loaded.object_joints),
            robot_joints=list(loaded.robot_joints),
            still=True,
            coasting=True,
        )


def test_motion_robot_takes_declared_still_or_coasting(tmp_path: Path) -> None:
    from tiny_scene import write_tiny_scene

    scene = write_tiny_scene(
        tmp_path, scene=ARM_AND_PUCK_SCENE.replace("ROBOT", 'robot = "frozen"'), model=ARM_AND_PUCK
    )
    with pytest.raises(
        EnergyMarginError, match=r"scene.toml:10: motion.robot: must be one of 'declared', 'still', 'coasting'"
    ):
        read_scene_file(scene)


def test_wrench_bounds_count_the_armature_of_the_objects_joints(tmp_path: Path) -> None:
    from tiny_scene import write_tiny_scene

    with_armature = ARM_AND_PUCK.replace(
        '<joint name="puck_x" type="slide" axis="1 0 0"/>',
        '<joint name="puck_x" type="slide" axis="1 0 0" armature="0.4"/>',
    )
    scene = write_tiny_scene(tmp_path, scene=ARM_AND_PUCK_SCENE.replace("ROBOT", ""), model=with_armature)
    task = get_task("scene", {"scene_file": str(scene)})
    limits = task.wrench_limits(task.build_scene(1, 0.5)).max_wrench
    # (0.1 kg + armature) x the linear bound (the default: 2 m/s^2 in x and y, none along z).
    bound = task.loaded.perturbation.linear_acceleration
    assert bound == (2.0, 2.0, 0.0)
    np.testing.assert_allclose(limits[0, :3], [(0.1 + 0.4) * bound[0], 0.1 * bound[1], 0.0])
    # An upright puck takes no torque about x and y; about z its inertia times the default bound.
    np.testing.assert_allclose(limits[0, 3:5], 0.0)
    body = int(task.loaded.object_bodies[0])
    alpha_z = task.loaded.perturbation.angular_acceleration[2]
    assert alpha_z == 20.0
    assert limits[0, 5] == pytest.approx(task.loaded.model.body_inertia[body, 2] * alpha_z)


def test_a_tight_strip_is_filled_by_starting_the_layout_again(make_scene) -> None:
    # Two 6 cm boxes 0.1 m apart on a 0.12 m strip: the first box placed in the middle leaves the
    # second no room (the layout used to fail there); a fresh layout finds the ends.
    strip = "[randomize.start]\nx = [-0.06, 0.06]\ny = [0.02, 0.02]\nmin_separation = 0.1\n"
    task = get_task(
        "scene",
        {
            "scene_file": str(
                make_scene(
                    replace={"[randomize.start]\nx = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n": strip}
                )
            )
        },
    )
    for seed in range(12):
        initial = task.sample_trajectory(np.random.default_rng(seed), 2).initial
        assert abs(initial.object_pos[0, 0] - initial.object_pos[1, 0]) > 0.1
        assert np.all(np.abs(initial.object_pos[:, 0]) <= 0.06)


def test_an_impossible_layout_names_the_object_the_ranges_and_a_grids_capacity(
    make_scene, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    strip = "[randomize.start]\nx = [-0.04, 0.04]\ny = [0.02, 0.02]\nmin_separation = 0.1\n"
    scene = make_scene(replace={"[randomize.start]\nx = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n": strip})
    for command in (["scene", str(scene), "--no-picture"], ["scene", str(scene), "--picture", str(tmp_path / "p.png")]):
        status = main(command)
        error = capsys.readouterr().err
        if "--no-picture" in command:
            assert status == 0  # the summary draws no layout
            continue
        assert status == 2
        assert error.count("\n") == 1 and "ValueError" not in error, error
        assert "cannot place 2 objects 0.1 m apart (x in [-0.04, 0.04] m, y in [0.02, 0.02] m)" in error
        assert "at most 1 fit in" in error and "box_b found no room" in error
        assert "a grid of 0.1 m spacing holds at most 1 origins there" in error
        assert not (tmp_path / "p.png").exists()


def test_a_start_on_the_robot_names_the_deepest_overlap(make_scene) -> None:
    on_pusher = "[randomize.start]\nx = [-0.1, 0.1]\ny = [-0.15, -0.15]\n"
    task = get_task(
        "scene",
        {
            "scene_file": str(
                make_scene(
                    replace={"[randomize.start]\nx = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n": on_pusher}
                )
            )
        },
    )
    with pytest.raises(
        ValueError, match=r"without overlap in 200 draws \(the last: box_[ab] [0-9.]+ mm into the robot"
    ):
        task.sample_trajectory(np.random.default_rng(0), 2)


def _follow_task(make_scene, follow: bool):  # type: ignore[no-untyped-def]
    replace = {"[capture]\n": f"[capture]\nfollow = {str(follow).lower()}\n"}
    return get_task("scene", {"scene_file": str(make_scene(replace=replace))})


def test_a_following_capture_region_is_built_at_every_states_own_robot_pose(make_scene) -> None:
    from energy_margin.world.state import FrameState

    frozen_task, follow_task = _follow_task(make_scene, False), _follow_task(make_scene, True)
    assert follow_task.loaded.spec.capture_follows and not frozen_task.loaded.spec.capture_follows
    from energy_margin.report.scene_view import describe_scene

    assert any("capture region follows the robot (attached" in line for line in describe_scene(follow_task))
    assert any(
        "capture region fixed at the analysed frame (follow = false" in line for line in describe_scene(frozen_task)
    )
    # The pusher (a mocap body: robot_q holds its position, then its quaternion) at y = -0.15 with
    # both boxes in its band (y from -0.13 to 0.07), then a state where the pusher went on to
    # y = 0.15 and took the boxes along to y = 0.27, inside the band it carries but not the first one.
    pusher = lambda y: np.array([0.0, y, 0.03, 1.0, 0.0, 0.0, 0.0])  # noqa: E731
    root = FrameState(
        object_pos=np.array([[-0.06, -0.03, 0.03], [0.06, -0.03, 0.03]]),
        object_quat=np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)),
        object_vel=np.zeros((2, 6)),
        robot_q=pusher(-0.15),
        robot_v=np.zeros(7),
    )
    object_pos = np.stack([root.object_pos, root.object_pos + np.array([0.0, 0.3, 0.0])])
    object_vel = np.zeros((2, 2, 6))
    object_quat = np.stack([root.object_quat, root.object_quat])
    robot_q = np.stack([pusher(-0.15), pusher(0.15)])
    frozen = frozen_task.capture_inside(root, object_pos, object_vel, object_quat, robot_q)
    follow = follow_task.capture_inside(root, object_pos, object_vel, object_quat, robot_q)
    assert frozen.tolist() == [True, False]
    assert follow.tolist() == [True, True]
    with pytest.raises(InvalidParameterError, match=r"capture region follows the robot .*capture\.follow = false"):
        follow_task.capture_inside(root, object_pos, object_vel, object_quat, None)


def test_trees_keep_the_robot_coordinates_of_every_node(make_scene) -> None:
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame

    task = _follow_task(make_scene, True)
    trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
    scores, field = analyze_frame(
        task,
        trajectory.initial,
        friction=trajectory.friction,
        drive=trajectory.drive,
        seed=1,
        # The tree's own score: the start is not captured, which the default's gate would score 0.
        config=AnalyzerConfig(expansions=40, capture_gate="none"),
    )
    assert not task.is_captured(trajectory.initial)
    assert field.robot_q is not None and field.robot_q.shape == (field.nodes, 7)
    np.testing.assert_array_equal(field.robot_q[0], trajectory.initial.robot_q)
    # The pusher follows its motion through the tree: deeper nodes are further along +y.
    assert np.max(field.robot_q[:, 1]) > trajectory.initial.robot_q[1]
    expected = task.capture_inside(
        trajectory.initial, field.object_pos, field.object_vel, field.object_quat, field.robot_q
    )
    from energy_margin.analysis.scores import region_score

    assert scores.capture_score == region_score(field.costs, expected, task.config.likelihood_lambda)
    # A batched expansion of a model with mocap bodies keeps them too (the mocap poses of each node's command).
    _, batched_field = analyze_frame(
        task,
        trajectory.initial,
        friction=trajectory.friction,
        drive=trajectory.drive,
        seed=1,
        config=AnalyzerConfig(expansions=8, batch=2),
    )
    assert batched_field.robot_q is not None and batched_field.robot_q.shape == (batched_field.nodes, 7)
    assert np.max(batched_field.robot_q[:, 1]) > trajectory.initial.robot_q[1]


def test_follow_with_batched_expansion_of_a_mocap_model_is_analysed(
    make_scene, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = make_scene(replace={"[capture]\n": "[capture]\nfollow = true\n"})
    out = tmp_path / "d"
    assert main(["generate", "--scene", str(scene), "--trajectories", "1", "--frames", "2", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["analyze", str(out), "--expansions", "8", "--batch", "2", "--no-progress"]) == 0
    assert (out / "scores.csv").exists()


def test_a_zero_separation_layout_failure_is_still_one_line(make_scene) -> None:
    point = "[randomize.start]\nx = [0.0, 0.0]\ny = [0.02, 0.02]\nmin_separation = 0.0\n"
    task = get_task(
        "scene",
        {
            "scene_file": str(
                make_scene(
                    replace={"[randomize.start]\nx = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n": point}
                )
            )
        },
    )
    with pytest.raises(InvalidDataError, match="cannot place 2 objects 0 m apart") as error:
        task.sample_trajectory(np.random.default_rng(0), 2)
    assert "grid" not in str(error.value)


def test_the_spec_records_which_keys_the_file_leaves_to_their_defaults(tiny_scene: Path) -> None:
    spec = read_scene_file(tiny_scene)
    assert isinstance(spec.defaulted, frozenset)
    # The keys with a default that the tiny scene writes; it leaves the others out.
    written = {
        "motion.duration",
        "randomize.friction",
        "randomize.start.x",
        "randomize.start.y",
        "randomize.start.yaw",
        "perturbation.linear_acceleration",
        "perturbation.angular_acceleration",
        "perturbation.max_duration",
    }
    assert not written & spec.defaulted
    assert spec.defaulted == (set(DEFAULTED_KEYS) | {"randomize.start.z"}) - written
    # A pile has no per-axis ranges; a design parameter without a default takes the model's value.
    pile = tiny_scene.read_text().replace(
        "x = [-0.12, 0.12]\ny = [-0.02, 0.08]\nyaw = [-0.3, 0.3]\n",
        'mode = "pile"\nlow = [-0.1, -0.1, 0.03]\nhigh = [0.1, 0.1, 0.03]\n',
    )
    pile += '\n[design]\nwidth = { geom = "pusher", attribute = "size", index = 0, low = 0.1, high = 0.2 }\n'
    tiny_scene.write_text(pile)
    spec = read_scene_file(tiny_scene)
    assert "randomize.start.mode" not in spec.defaulted and "randomize.start.x" not in spec.defaulted
    assert "design.width.default" in spec.defaulted
