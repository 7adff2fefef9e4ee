"""Regions on a body the robot moves follow it by default (tasks/scene_follow.py), capture and success alike."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.errors import EnergyMarginError
from energy_margin.planning.propagate import _propagate_one, _propagate_round
from energy_margin.sim.base import BatchedRollout, require
from energy_margin.tasks import get_task
from energy_margin.tasks.region_types import FrameRegions
from energy_margin.tasks.regions import build_region, builds_stacked
from energy_margin.tasks.scene_file import read_scene_file
from energy_margin.tasks.scene_follow import node_frames
from energy_margin.tasks.scene_model import load_scene
from energy_margin.tasks.scene_sections import region_names
from energy_margin.world.state import FrameState
from tiny_scene import SLIDE_PAD

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

#: A two-link arm on actuated hinges (the second link carries the site "tip") beside the tiny scene's
#: boxes, a shelf fixed to the world, a goal marker on a slide no actuator drives and a lid on a free box.
ARM_MODEL = """<mujoco model="arm">
  <option timestep="0.01"/>
  <worldbody>
    <geom name="ground" type="plane" size="2 2 0.1"/>
    <body name="shelf" pos="0 0.5 0.1"><geom type="box" size="0.1 0.1 0.01"/><site name="shelf_top"/></body>
    <body name="marker" pos="0.3 0.5 0.01">
      <joint name="marker_x" type="slide" axis="1 0 0"/><geom type="sphere" size="0.01" contype="0" conaffinity="0"/>
    </body>
    <body name="upper" pos="0 -0.4 0.05">
      <joint name="shoulder" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0 0.2 0" size="0.02"/>
      <body name="fore" pos="0 0.2 0">
        <joint name="elbow" type="hinge" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0 0.15 0" size="0.02"/>
        <site name="tip" pos="0 0.15 0"/>
      </body>
    </body>
    <body name="box_a" pos="-0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/>
      <body name="lid" pos="0 0 0.03"><geom type="box" size="0.03 0.03 0.005" mass="0.01"/></body></body>
    <body name="box_b" pos="0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>
  </worldbody>
  <actuator><position joint="shoulder" kp="10"/><position joint="elbow" kp="10"/></actuator>
</mujoco>
"""

ARM_SCENE = """schema_version = 1
mjcf = "model.xml"

[objects]
bodies = ["box_a", "box_b"]

[motion]
duration = 1.0

[[motion.keyframes]]
time = 0.0
ctrl = [0.0, 0.0]

[capture]
CAPTURE
region = { type = "box", site = "tip", center = [0.0, 0.0, 0.0], half_size = [0.1, 0.1, 0.1] }

[success]
SUCCESS
"""


def _arm(tmp_path: Path, capture: str = "", success: str = "") -> Path:
    directory = tmp_path / f"arm{len(list(tmp_path.iterdir()))}"
    directory.mkdir()
    (directory / "model.xml").write_text(ARM_MODEL)
    text = ARM_SCENE.replace("CAPTURE\n", capture).replace("SUCCESS\n", success)
    path = directory / "scene.toml"
    path.write_text(text)
    return path


WORLD_BOX = 'region = { type = "box", center = [0.0, 0.5, 0.1], half_size = [0.1, 0.1, 0.1] }\n'


def test_a_region_on_a_hinged_link_follows_and_names_its_nearest_joint(tmp_path: Path) -> None:
    loaded = load_scene(_arm(tmp_path, success=WORLD_BOX))
    capture, success = loaded.follow["capture"], loaded.follow["success"]
    assert capture.follows and not capture.stated and loaded.spec.capture_follows is True
    assert capture.describe() == "follows the robot (attached to body 'fore', moved by joint 'elbow') (default)"
    assert not success.follows and loaded.spec.success_follows is False
    assert success.describe() == "fixed in the world (default)"


@pytest.mark.parametrize(
    ("success", "follows", "text"),
    [
        # A site on a body welded to the world: fixed in the world.
        (
            'region = { type = "distance", site = "shelf_top", max = 0.1 }\n',
            False,
            "fixed in the world (default)",
        ),
        # A marker on a slide joint that no actuator drives: the robot does not move it.
        (
            'region = { type = "distance", body = "marker", max = 0.1 }\n',
            False,
            "fixed at the analysed frame (attached to body 'marker', which the robot does not move) (default)",
        ),
        # A body that rides on an object (its free joint is no robot joint): frozen at the analysed frame.
        (
            'region = { type = "height", body = "lid", max = 0.1 }\n',
            False,
            "fixed at the analysed frame (attached to body 'lid', which the robot does not move) (default)",
        ),
        # Any part of a composed region on the arm makes the whole region follow.
        (
            'region = { type = "all", of = [{ type = "speed", max = 0.1 }, '
            '{ type = "distance", body = "upper", max = 0.3 }] }\n',
            True,
            "follows the robot (attached to body 'upper', moved by joint 'shoulder') (default)",
        ),
        # The file decides: follow = false freezes a region on the arm, follow = true makes any region follow.
        (
            'follow = false\nregion = { type = "distance", site = "tip", max = 0.1 }\n',
            False,
            "fixed at the analysed frame (follow = false; attached to body 'fore', moved by joint 'elbow')",
        ),
        (
            "follow = true\n" + WORLD_BOX,
            True,
            "follows the robot (follow = true; attached to no body the robot moves)",
        ),
    ],
)
def test_a_success_region_follows_where_it_is_attached_unless_the_file_says(
    tmp_path: Path, success: str, follows: bool, text: str
) -> None:
    loaded = load_scene(_arm(tmp_path, success=success))
    assert loaded.follow["success"].follows is follows and loaded.spec.success_follows is follows
    assert loaded.follow["success"].describe() == text


#: A hand welded to a mocap body at the end of an arm whose hinges no actuator drives (as Fetch's), and
#: a second arm driven through a tendon.
WELDED_MODEL = """<mujoco model="welded">
  <worldbody>
    <body name="hand_target" mocap="true" pos="0 0.3 0.1"/>
    <body name="upper" pos="0 0 0.1">
      <joint name="shoulder" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0 0.15 0" size="0.02"/>
      <body name="hand" pos="0 0.15 0">
        <joint name="wrist" type="hinge" axis="0 0 1"/>
        <geom type="box" size="0.03 0.03 0.03"/><site name="palm"/>
      </body>
    </body>
    <body name="other" pos="0.5 0 0.1">
      <joint name="other_hinge" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0 0.15 0" size="0.02"/><site name="other_tip" pos="0 0.15 0"/>
    </body>
  </worldbody>
  <equality><weld body1="hand_target" body2="hand"/></equality>
  <tendon><fixed name="drive"><joint joint="other_hinge" coef="1"/></fixed></tendon>
  <actuator><motor tendon="drive"/></actuator>
</mujoco>
"""


@pytest.mark.parametrize(
    ("element", "mover"),
    [
        ('site = "palm"', "mocap body 'hand_target' (welded to body 'hand')"),
        ('body = "upper"', "joint 'shoulder'"),  # pulled along by the welded hand
        ('site = "other_tip"', "joint 'other_hinge'"),  # a motor on a tendon over the hinge
    ],
)
def test_welds_to_mocap_bodies_and_tendons_move_bodies_with_the_robot(element: str, mover: str) -> None:
    import mujoco

    from energy_margin.tasks.scene_follow import region_follow

    model = mujoco.MjModel.from_xml_string(WELDED_MODEL)
    robot = [joint for joint in range(model.njnt)]
    follow = region_follow(
        "capture", {"type": "distance", **_table(element), "max": 0.1}, None, model, robot, object_joints=()
    )
    assert follow.follows and follow.moving[0].mover == mover


def _table(element: str) -> dict[str, str]:
    key, value = element.split(" = ")
    return {key: value.strip('"')}


def test_the_scene_command_says_which_region_follows_and_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = _arm(tmp_path, capture="follow = false\n", success=WORLD_BOX)
    assert main(["scene", str(scene), "--no-picture"]) == 0
    out = capsys.readouterr().out
    assert (
        "; capture region fixed at the analysed frame (follow = false; attached to body 'fore', moved by joint "
        "'elbow')\n" in out
    )
    assert "; success region fixed in the world (default)\n" in out


def test_a_follow_that_is_not_a_bool_is_a_line_exact_error(tmp_path: Path) -> None:
    scene = _arm(tmp_path, success='follow = "yes"\n' + WORLD_BOX)
    line = scene.read_text().splitlines().index('follow = "yes"') + 1
    with pytest.raises(EnergyMarginError, match=rf"scene\.toml:{line}: success\.follow: must be true or false"):
        read_scene_file(scene)


def _pusher_state(y: float, boxes_y: float) -> FrameState:
    return FrameState(
        object_pos=np.array([[-0.06, boxes_y, 0.03], [0.06, boxes_y, 0.03]]),
        object_quat=np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)),
        object_vel=np.zeros((2, 6)),
        robot_q=np.array([0.0, y, 0.03, 1.0, 0.0, 0.0, 0.0]),
        robot_v=np.zeros(7),
    )


@pytest.mark.parametrize("follow", ["", "follow = true\n", "follow = false\n"])
def test_a_success_region_on_the_pusher_is_tested_at_every_states_own_pose(make_scene, follow: str) -> None:
    # Success: within 0.16 m of the pusher; the tiny scene's mocap pusher carries it.
    scene = make_scene()
    text = scene.read_text()
    success = f'[success]\n{follow}region = {{ type = "distance", body = "pusher", max = 0.16 }}\n'
    scene.write_text(text[: text.index("[success]")] + success)
    task = get_task("scene", {"scene_file": str(scene)})
    root = _pusher_state(-0.15, -0.03)
    moved = _pusher_state(0.15, 0.27)  # the pusher went on and took the boxes along
    object_pos = np.stack([root.object_pos, moved.object_pos])
    object_vel = np.zeros((2, 2, 6))
    object_quat = np.stack([root.object_quat, moved.object_quat])
    robot_q = np.stack([root.robot_q, moved.robot_q])
    inside = task.success_inside(root, object_pos, object_vel, object_quat, robot_q)
    following = follow != "follow = false\n"
    assert task.loaded.spec.success_follows is following
    assert inside.tolist() == ([True, True] if following else [True, False])
    # The analysis scores a tree's success with the same test (each node's robot coordinates).
    from energy_margin.analysis.frame import field_membership
    from energy_margin.planning.nodes import CostField

    field = CostField(
        costs=np.array([0.0, 1.0]),
        object_pos=object_pos,
        object_vel=object_vel,
        parents=np.array([-1, 0]),
        times=np.array([0.0, 0.5]),
        expansions=1,
        physics_s=0.0,
        total_s=0.0,
        object_quat=object_quat,
        robot_q=robot_q,
    )
    assert field_membership(task, root, field)[1].tolist() == inside.tolist()


def test_the_default_analyses_as_follow_true_and_not_as_follow_false(make_scene) -> None:
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame

    scores = {}
    for follow in ("", "follow = true\n", "follow = false\n"):
        task = get_task("scene", {"scene_file": str(make_scene(replace={"[capture]\n": f"[capture]\n{follow}"}))})
        trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
        result, _ = analyze_frame(
            task,
            trajectory.initial,
            friction=trajectory.friction,
            drive=trajectory.drive,
            seed=3,
            # The tree's own score (the start is not captured: the default's gate scores it 0).
            config=AnalyzerConfig(expansions=40, capture_gate="none"),
        )
        scores[follow] = result.capture_score
    assert scores[""] == scores["follow = true\n"]
    assert scores[""] != scores["follow = false\n"]


def _both_paths(task, root: FrameState, friction: float, drive: np.ndarray):  # type: ignore[no-untyped-def]
    """Six expansions of ``root`` batched and one at a time: the outcomes of each path."""
    simulator = task.make_simulator(2, friction, drive)
    simulator.reset(root)
    propagator = require(simulator, BatchedRollout, purpose="the test").rollout_propagator(1)
    rng = np.random.default_rng(5)
    k = 6
    # Parents at different script times (the pusher's command differs), wrenches and lengths at random.
    times = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    wrenches = rng.uniform(-0.2, 0.2, size=(k, 2, 6)) * np.array([1, 1, 0, 0, 0, 0.01])
    n_steps = rng.integers(3, 12, size=k)
    batched_tree = SimpleNamespace(states=np.stack([propagator.current_state()] * k), times=times)
    round_ = [(j, j, wrenches[j], int(n_steps[j])) for j in range(k)]
    batched = _propagate_round(propagator, task, drive, batched_tree, round_, 0.0, 2)
    one_tree = SimpleNamespace(states=np.stack([simulator.get_state()] * k), times=times)
    single = [
        _propagate_one(simulator, task, drive, one_tree, j, wrenches[j], int(n_steps[j]), 0.0, 2, False)
        for j in range(k)
    ]
    return batched, single


def test_batched_and_one_at_a_time_propagation_give_the_same_robot_and_membership(make_scene) -> None:
    task = get_task("scene", {"scene_file": str(make_scene())})
    assert task.loaded.spec.capture_follows  # by default: the band is in the mocap pusher's frame
    trajectory = task.sample_trajectory(np.random.default_rng(1), 2)
    root = trajectory.initial
    batched, single = _both_paths(task, root, trajectory.friction, trajectory.drive)
    k = len(batched)
    robots = np.stack([outcome.robot for outcome in batched])
    expected = np.stack([outcome.robot for outcome in single])
    assert robots.shape == (k, 7)
    # The mocap pose is the command's at the last control period: the same in both paths.
    np.testing.assert_allclose(robots, expected, atol=1e-12)
    assert np.ptp(robots[:, 1]) > 0.1  # the pusher is at other places in other states
    pos = np.stack([outcome.pos for outcome in batched])
    vel = np.stack([outcome.vel for outcome in batched])
    quat = np.stack([outcome.quat for outcome in batched])
    one_pos = np.stack([outcome.pos for outcome in single])
    np.testing.assert_allclose(pos, one_pos, atol=1e-4)
    membership = task.capture_inside(root, pos, vel, quat, robots)
    one_membership = task.capture_inside(
        root, one_pos, np.stack([o.vel for o in single]), np.stack([o.quat for o in single]), expected
    )
    assert membership.tolist() == one_membership.tolist()
    # Frozen at the root the membership differs: following is what the batched path now allows.
    assert membership.tolist() != task.capture_regions([root] * k).contains(pos).all(axis=-1).tolist()


def test_a_mocap_body_without_declared_poses_stays_where_the_frame_has_it_in_both_paths(make_scene) -> None:
    # The motion drives a slide by its actuator only; the mocap pusher has no keyframes.
    scene = make_scene(
        replace={
            "mocap.pusher.pos = [0.0, -0.15, 0.03]": "ctrl = [0.0]",
            "mocap.pusher.pos = [0.0, 0.3, 0.03]": "ctrl = [0.1]",
        },
        model_replace=SLIDE_PAD,
    )
    task = get_task("scene", {"scene_file": str(scene)})
    trajectory = task.sample_trajectory(np.random.default_rng(1), 2)
    root = trajectory.initial
    robot_q = root.robot_q.copy()
    robot_q[1 + 1] = 0.1  # the pusher's y (after the pad's joint) where this frame has it, not the model's
    root = FrameState(root.object_pos, root.object_quat, root.object_vel, robot_q, root.robot_v)
    batched, single = _both_paths(task, root, trajectory.friction, trajectory.drive)
    robots = np.stack([outcome.robot for outcome in batched])
    np.testing.assert_allclose(robots[:, 1:], np.stack([outcome.robot for outcome in single])[:, 1:], atol=1e-12)
    np.testing.assert_allclose(robots[:, 2], 0.1)


def _before(path: Path) -> tuple[bool, bool]:
    """(capture, success) follow of an example as resolved before the default: the file's capture.follow, no success."""
    text = path.read_text()
    capture = text[text.index("[capture]") : text.index("[success]")]
    return ("follow = true" in capture, False)


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*/*.toml")), ids=lambda path: path.parent.name)
def test_every_example_scene_resolves_to_the_follow_setting_it_had(path: Path) -> None:
    spec = read_scene_file(path)
    capture_before, success_before = _before(path)
    # Each example writes capture.follow, so the default does not decide it.
    assert "capture.follow" not in spec.defaulted and spec.capture_follows is capture_before
    assert "success.follow" in spec.defaulted
    if not region_names(spec.success, "success.region"):
        return  # a success region attached to no element is fixed in the world whatever the model
    # Otherwise resolve it against the model (the examples whose success names an element ship theirs).
    loaded = load_scene(path)
    assert loaded.spec.success_follows is success_before
    assert loaded.spec.capture_follows is capture_before


#: The examples that write their scene file from Python (their models come from third-party packages).
WRITTEN_SCENES = sorted(path for path in EXAMPLES.glob("*/*.py") if "[capture]" in path.read_text())


def test_examples_writing_their_scene_from_python_keep_both_sets_at_the_analysed_state() -> None:
    # Their regions sit on grippers and fingers: without follow = false they would now follow them,
    # and their READMEs' figures were measured with the regions taken at the analysed state.
    assert len(WRITTEN_SCENES) == 5, WRITTEN_SCENES
    for path in WRITTEN_SCENES:
        text = path.read_text().replace("\\n", "\n")
        for name in ("capture", "success"):
            assert text.count(f"[{name}]\nfollow = false\n") == text.count(f"[{name}]\n") == 1, (path, name)


@pytest.mark.parametrize(
    ("region", "placed"),
    [
        ('{ type = "distance", site = "tip", max = 0.1 }', False),  # on the arm
        ('{ type = "distance", site = "shelf_top", max = 0.1 }', False),  # on the world
        ('{ type = "height", body = "lid", min = 0.0, max = 0.1 }', True),  # on box_a's free joint
        (
            '{ type = "all", of = [{ type = "distance", site = "tip", max = 0.3 }, '
            '{ type = "distance", body = "box_b", max = 0.3 }] }',
            True,
        ),
    ],
)
def test_a_region_is_built_without_the_objects_only_where_no_object_places_it(
    tmp_path: Path, region: str, placed: bool
) -> None:
    task = get_task("scene", {"scene_file": str(_arm(tmp_path, success=f"region = {region}\n"))})
    assert task.loaded.follow["success"].placed_by_objects is placed
    rng = np.random.default_rng(0)
    positions = rng.uniform(-0.4, 0.4, size=(64, 2, 3))
    # Objects moved away from the model's start, and the arm turned: the region is where the frame puts it.
    frame = FrameState(
        object_pos=np.array([[0.2, 0.1, 0.15], [-0.1, 0.2, 0.05]]),
        object_quat=np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)),
        object_vel=np.zeros((2, 6)),
        robot_q=np.array([0.7, -0.4, 0.05]),  # shoulder, elbow, the marker's slide
        robot_v=np.zeros(3),
    )
    region = task.success_region_at(frame)
    with_objects = build_region(task.loaded.spec.success, task.frame_lookup(frame, objects=True))
    np.testing.assert_array_equal(region.contains(positions), with_objects.contains(positions))
    without = build_region(task.loaded.spec.success, task.frame_lookup(frame, objects=False))
    # Left out where they place the region, the objects would move it: the check can fail.
    assert np.array_equal(without.contains(positions), region.contains(positions)) is not placed


@pytest.mark.parametrize(
    ("region", "stacked"),
    [
        ('{ type = "distance", site = "tip", min = 0.02, max = 0.25 }', True),
        ('{ type = "height", body = "box_b", min = -0.05, max = 0.05 }', True),  # on an object: placed by it
        (
            '{ type = "all", of = [{ type = "distance", body = "fore", max = 0.3 }, { type = "speed", max = 0.5 }] }',
            True,
        ),
        (
            '{ type = "any", of = [{ type = "not", region = { type = "distance", site = "tip", max = 0.3 } }, '
            '{ type = "distance", body = "box_b", max = 0.2 }] }',
            True,
        ),
        ('{ type = "box", site = "tip", center = [0.0, 0.0, 0.0], half_size = [0.15, 0.15, 0.15] }', False),
        (
            '{ type = "all", of = [{ type = "distance", site = "tip", max = 0.3 }, '
            '{ type = "box", site = "tip", center = [0.0, 0.0, 0.0], half_size = [0.2, 0.2, 0.2] }] }',
            False,
        ),
    ],
)
def test_the_regions_of_many_states_are_one_stacked_region_that_tests_as_one_per_state(
    tmp_path: Path, region: str, stacked: bool
) -> None:
    path = _arm(tmp_path, success=WORLD_BOX)
    tip_box = 'region = { type = "box", site = "tip", center = [0.0, 0.0, 0.0], half_size = [0.1, 0.1, 0.1] }\n'
    path.write_text(path.read_text().replace(tip_box, f"at_least = 1\nregion = {region}\n"))
    task = get_task("scene", {"scene_file": str(path)})
    assert builds_stacked(task.loaded.spec.capture) is stacked
    rng = np.random.default_rng(7)
    count = 40
    states = [
        FrameState(
            object_pos=rng.uniform(-0.3, 0.3, size=(2, 3)),
            object_quat=np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)),
            object_vel=rng.uniform(-1.0, 1.0, size=(2, 6)),
            robot_q=rng.uniform(-1.5, 1.5, size=3),
            robot_v=np.zeros(3),
        )
        for _ in range(count)
    ]
    positions = rng.uniform(-0.3, 0.3, size=(count, 2, 3)) + np.array([0.0, -0.15, 0.05])  # about the arm
    velocities = rng.uniform(-1.0, 1.0, size=(count, 2, 6))
    together = task.capture_regions(states)
    one_by_one = FrameRegions([task.capture_region(state) for state in states])
    assert isinstance(together, FrameRegions) is not stacked
    inside = together.contains(positions, velocities)
    np.testing.assert_array_equal(inside, one_by_one.contains(positions, velocities))
    assert 0 < inside.sum() < inside.size  # the test can tell the rows apart
    np.testing.assert_array_equal(together.signed_distance(positions), one_by_one.signed_distance(positions))
    # A tree's states: capture_inside measures every state against the region at its own pose (where
    # the region follows the robot; one on an object alone stays at the analysed frame).
    robot_q = np.stack([state.robot_q for state in states])
    nodes = node_frames(states[0], positions, velocities, None, robot_q)
    if task.loaded.spec.capture_follows:
        regions = FrameRegions([task.capture_region(node) for node in nodes])
        expected = np.all(regions.contains(positions, velocities), axis=-1)
    else:
        expected = np.all(task.capture_region(states[0]).contains(positions, velocities), axis=-1)
    np.testing.assert_array_equal(task.capture_inside(states[0], positions, velocities, None, robot_q), expected)
