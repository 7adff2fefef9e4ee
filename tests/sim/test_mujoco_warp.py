"""The ``mujoco-warp`` engine on the CPU device: the propagations of ``mujoco.rollout`` up to float32.

Skipped where MuJoCo Warp is not installed (the ``gpu`` extra; CI's ``gpu`` leg installs it). The
first propagation compiles Warp's kernels for the CPU (about 40 s on two cores, cached afterwards).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco_warp")

from energy_margin.analysis.config import AnalyzerConfig
from energy_margin.analysis.frame import FrameAnalyzer
from energy_margin.cli import main
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.sim import check_engine_device
from energy_margin.sim.base import IncompatibleModelsError
from energy_margin.sim.mujoco_warp import WarpModelSimulator, WarpPropagator, WarpSimulator
from energy_margin.tasks import get_task
from tiny_scene import TINY_MODEL, TINY_SCENE, write_tiny_scene

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def batch(tiny_dataset_source: Path):  # type: ignore[no-untyped-def]
    """Both engines reset to one frame of the tiny pushing set, and a batch of six perturbed propagations."""
    dataset = load_dataset(tiny_dataset_source)
    task = dataset.task
    friction, drive = float(dataset.arrays["friction"][0]), dataset.arrays["drive"][0]
    frame = dataset.frame(0, 1)
    reference = task.make_simulator(2, friction, drive)
    warp = WarpSimulator(task.build_scene(2, friction, drive), device="cpu")
    for simulator in (reference, warp):
        simulator.reset(frame)
    rng = np.random.default_rng(0)
    k = 6
    state = reference.rollout_propagator(1).current_state()
    inputs = (
        task,
        drive,
        np.repeat(state[None], k, axis=0),
        np.full(k, float(dataset.arrays["frame_time"][0, 1])),
        rng.uniform(-1, 1, (k, 2, 6)) * task.wrench_limits(reference.scene).max_wrench,
        rng.integers(5, 30, k),
        None,
    )
    return reference, warp, inputs


def test_warp_propagations_match_mujoco_rollout_up_to_float32(batch) -> None:  # type: ignore[no-untyped-def]
    reference, warp, inputs = batch
    propagator = warp.rollout_propagator()
    assert isinstance(propagator, WarpPropagator) and warp.rollout_propagator(4) is propagator
    np.testing.assert_array_equal(propagator.current_state(), reference.rollout_propagator(1).current_state())
    pos, _, quat, ends = reference.rollout_propagator(1).propagate(*inputs)
    w_pos, _, w_quat, w_ends = propagator.propagate(*inputs)
    assert w_ends.dtype == np.float64 and w_ends.shape == ends.shape
    n_steps = inputs[5]
    np.testing.assert_allclose(w_ends[:, 0], ends[:, 0], rtol=1e-6)  # each stopped at its own step
    assert np.abs(pos - pos.mean(axis=0)).max() > 1e-4  # the wrenches differ, and so do the outcomes
    np.testing.assert_allclose(w_pos, pos, atol=2e-3)
    np.testing.assert_allclose(np.abs(np.sum(w_quat * quat, axis=-1)), 1.0, atol=1e-3)
    assert np.all(n_steps >= 5)


def test_a_propagation_does_not_depend_on_its_batch(batch) -> None:  # type: ignore[no-untyped-def]
    _, warp, inputs = batch
    propagator = warp.rollout_propagator()
    task, drive, states, times, wrenches, n_steps, control = inputs
    together = propagator.propagate(*inputs)[3]
    alone = propagator.propagate(task, drive, states[2:3], times[2:3], wrenches[2:3], n_steps[2:3], control)[3]
    np.testing.assert_array_equal(alone[0], together[2])


def test_overflowing_buffers_grow_and_the_round_runs_again(batch) -> None:  # type: ignore[no-untyped-def]
    _, warp, inputs = batch
    expected = warp.rollout_propagator().propagate(*inputs)[3]
    small = WarpPropagator(warp.model, warp.data, warp.index, "cpu")
    small.contacts_per_world, small.constraints_per_world = 1, 1
    got = small.propagate(*inputs)[3]
    assert small.regrown >= 1 and small.contacts_per_world > 1
    np.testing.assert_allclose(got, expected, atol=1e-5)


def test_scores_on_warp_follow_those_on_mujoco(tiny_dataset_source: Path) -> None:
    dataset = load_dataset(tiny_dataset_source)
    indices = list(range(dataset.n_trajectories * dataset.n_frames))
    config = AnalyzerConfig(expansions=60, batch=10)
    reference = [FrameAnalyzer(dataset, config, seed=1)(index) for index in indices]
    warp_config = AnalyzerConfig(expansions=60, batch=10, engine="mujoco-warp", device="cpu")
    warp = list(FrameAnalyzer(dataset, warp_config, seed=1).rows(indices))
    assert [row["expansions"] for row in warp] == [60] * len(indices)
    for key in ("capture_score", "success_score"):
        a = np.array([row[key] for row in reference])
        b = np.array([row[key] for row in warp])
        assert np.abs(a - b).mean() < 0.05, key


def test_the_fast_contact_model_runs_on_warp(tiny_dataset_source: Path) -> None:
    """The task's MuJoCo stand-ins (footprints, spheres) are built for Warp as for C MuJoCo."""
    dataset = load_dataset(tiny_dataset_source)
    indices = [0, 1, 2]
    config = AnalyzerConfig(expansions=12, batch=6, contacts="fast")
    reference = [FrameAnalyzer(dataset, config, seed=1)(index) for index in indices]
    analyzer = FrameAnalyzer(dataset, dataclasses.replace(config, engine="mujoco-warp", device="cpu"), seed=1)
    warp = list(analyzer.rows(indices))
    assert analyzer._lead is not None and analyzer._lead.scene.ground_contact == "footprint"  # type: ignore[attr-defined]
    for key in ("capture_score", "success_score"):
        a = np.array([row[key] for row in reference])
        b = np.array([row[key] for row in warp])
        assert np.abs(a - b).mean() < 0.05, key


def _together_scores_as_alone(
    dataset: Dataset, config: AnalyzerConfig, indices: list[int], *, seed: int
) -> FrameAnalyzer:
    """Assert the frames grown together score exactly as each alone; the analyzer that grew them together."""
    analyzer = FrameAnalyzer(dataset, config, seed=seed)
    together = list(analyzer.rows(indices))
    alone = [FrameAnalyzer(dataset, config, seed=seed)(index) for index in indices]
    for one, other in zip(alone, together, strict=True):
        assert (other["capture_score"], other["success_score"]) == (one["capture_score"], one["success_score"])
    return analyzer


def test_frames_of_several_roll_outs_grown_together_score_as_alone(tiny_dataset_source: Path) -> None:
    """One call holds both roll-outs' worlds, each with its own friction (a per-world model field)."""
    dataset = load_dataset(tiny_dataset_source)
    indices = list(range(dataset.n_trajectories * dataset.n_frames))
    config = AnalyzerConfig(expansions=30, batch=6, engine="mujoco-warp", device="cpu")
    analyzer = _together_scores_as_alone(dataset, config, indices, seed=2)
    propagator = analyzer._lead.rollout_propagator()  # type: ignore[union-attr]
    assert propagator.rounds == 5  # 30 expansions, 6 a round: every call held all six trees


def test_roll_outs_with_their_own_servo_gains_grow_together(tmp_path: Path) -> None:
    """Scooping's drive sets each roll-out's servo gains: per-world actuator parameters in one call."""
    from energy_margin.data.generate import generate_dataset

    dataset = generate_dataset("scooping", n_objects=2, n_trajectories=2, n_frames=2, seed=0, out=tmp_path / "s")
    gains = {dataset.task.make_simulator(2, float(f), d).model.actuator_gainprm.tobytes()
             for f, d in zip(dataset.arrays["friction"], dataset.arrays["drive"], strict=True)}  # fmt: skip
    assert len(gains) == 2  # the two roll-outs' models differ in more than friction
    indices = [0, 1, 2, 3]
    config = AnalyzerConfig(expansions=12, batch=6, engine="mujoco-warp", device="cpu")
    analyzer = _together_scores_as_alone(dataset, config, indices, seed=4)
    assert analyzer._lead.rollout_propagator().rounds == 2  # type: ignore[union-attr]


def test_a_model_of_another_structure_is_refused(batch) -> None:  # type: ignore[no-untyped-def]
    _, warp, inputs = batch
    other = get_task("pushing").make_simulator(3, 0.5).model
    with pytest.raises(IncompatibleModelsError, match="differ in"):
        warp.rollout_propagator().propagate(*inputs, [other] * len(inputs[2]))


def test_analyze_on_warp_records_its_versions_and_resumes(
    tiny_dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["analyze", str(tiny_dataset), "--engine", "mujoco-warp", "--device", "cpu", "--batch", "8",
            "--expansions", "16", "--no-progress"]  # fmt: skip
    assert main(args) == 0
    description = json.loads((tiny_dataset / "analysis.json").read_text())
    assert description["analyzer"]["engine"] == "mujoco-warp" and description["analyzer"]["device"] == "cpu"
    assert {"mujoco-warp", "warp-lang"} <= set(description["versions"])
    scores = (tiny_dataset / "scores.csv").read_text()
    capsys.readouterr()
    assert main(args) == 0
    assert (tiny_dataset / "scores.csv").read_text() == scores


def test_cuda_is_refused_in_one_line_where_there_is_none() -> None:
    import warp as wp

    if wp.is_cuda_available():
        pytest.skip("this machine has a CUDA device")
    with pytest.raises(EnergyMarginError, match="Warp finds no CUDA device here"):
        check_engine_device("mujoco-warp", "cuda")


#: The tiny scene with its pusher on a slide joint driven by a position servo instead of a mocap body.
SLIDE_MODEL = (
    TINY_MODEL.replace(
        '<body name="pusher" mocap="true" pos="0 -0.15 0.03">',
        '<body name="pusher" pos="0 -0.15 0.03"><joint name="push" type="slide" axis="0 1 0" damping="5"/>',
    )
    .replace(
        '<geom name="pusher" type="box" size="0.15 0.02 0.03"/>',
        '<geom name="pusher" type="box" size="0.15 0.02 0.03" mass="1"/>',
    )
    .replace("</worldbody>", '</worldbody><actuator><position joint="push" kp="300"/></actuator>')
)
SLIDE_SCENE = TINY_SCENE.replace("mocap.pusher.pos = [0.0, -0.15, 0.03]", "ctrl = [0.0]").replace(
    "mocap.pusher.pos = [0.0, 0.3, 0.03]", "ctrl = [0.45]"
)


@pytest.mark.parametrize("servo", [False, True], ids=["mocap pusher", "servo pusher"])
def test_a_scene_file_runs_on_warp_with_its_success_continued(tmp_path: Path, servo: bool) -> None:
    """A user's model on the GPU engine: one root a call with a mocap body, else every frame grown together."""
    scene = write_tiny_scene(tmp_path / "scene", *((SLIDE_SCENE, SLIDE_MODEL) if servo else ()))
    dataset = generate_dataset("scene", n_objects=2, n_trajectories=2, n_frames=2, seed=0, out=tmp_path / "d",
                               task_config={"scene_file": str(scene)})  # fmt: skip
    indices = [0, 1, 2, 3]
    config = AnalyzerConfig(expansions=12, batch=6, engine="mujoco-warp", device="cpu", continuation=4)
    analyzer = _together_scores_as_alone(dataset, config, indices, seed=6)
    assert isinstance(analyzer._simulator(float(dataset.arrays["friction"][0]), dataset.arrays["drive"][0]),
                      WarpModelSimulator)  # fmt: skip
    assert (analyzer._lead is not None) is servo  # grown together only without mocap bodies
    reference = [FrameAnalyzer(dataset, AnalyzerConfig(expansions=12, batch=6, continuation=4), seed=6)(index)
                 for index in indices]  # fmt: skip
    warp = list(FrameAnalyzer(dataset, config, seed=6).rows(indices))
    for key in ("capture_score", "success_score"):
        a = np.array([row[key] for row in reference])
        b = np.array([row[key] for row in warp])
        assert np.abs(a - b).mean() < 0.1, key


def test_roll_outs_following_their_recorded_paths_grow_together_on_warp(tmp_path: Path) -> None:
    """Each roll-out's own path (its drive parameters) rides in the worlds of one call, under the path's armature."""
    from energy_margin.data.record import record_dataset
    from energy_margin.tasks.recorded_path import RECORDED_ARMATURE
    from tiny_scene import ARM_OVER_PUCK, ARM_SCENE, write_arm_rollouts

    scene = write_tiny_scene(tmp_path / "scene", ARM_SCENE.replace("ROBOT", 'robot = "recorded"'), ARM_OVER_PUCK)
    dataset = record_dataset(scene, write_arm_rollouts(tmp_path / "rollouts", count=2), n_frames=2,
                             out=tmp_path / "set")  # fmt: skip
    config = AnalyzerConfig(expansions=12, batch=6, engine="mujoco-warp", device="cpu", continuation=4)
    analyzer = _together_scores_as_alone(dataset, config, [0, 1, 2, 3], seed=2)
    simulator = analyzer._simulator(float(dataset.arrays["friction"][0]), dataset.arrays["drive"][0])
    assert isinstance(simulator, WarpModelSimulator) and simulator.coasting
    assert simulator.model.dof_armature[simulator.index.robot_qvel[0]] == RECORDED_ARMATURE
