"""An analysis of the pruned model scores as one of the full model when no dropped pair touches."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.cli.analyze import add_arguments, analyzer_config
from energy_margin.errors import InvalidParameterError
from energy_margin.tasks import get_task
from tiny_scene import sweeping_arm

SCENE = """schema_version = 1
mjcf = "model.xml"

[objects]
bodies = ["box"]

[motion]
duration = 0.5

[[motion.keyframes]]
time = 0.0
ctrl = [0.5, 0.02, -0.02]

[capture]
follow = false
region = { type = "distance", site = "tip", max = 0.3 }

[success]
region = { type = "box", center = [0.0, 0.4, 0.03], half_size = [0.2, 0.2, 0.1] }
"""


@pytest.fixture(scope="module")
def arm_task(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    directory = tmp_path_factory.mktemp("arm")
    (directory / "model.xml").write_text(sweeping_arm(timestep=0.004))
    (directory / "scene.toml").write_text(SCENE)
    task = get_task("scene", {"scene_file": str(directory / "scene.toml")})
    return task, task.sample_trajectory(np.random.default_rng(0), 1)


def _scores(arm_task, model: str, seed: int):  # type: ignore[no-untyped-def]
    task, trajectory = arm_task
    simulator = task.make_simulator(1, trajectory.friction, trajectory.drive)
    scores, field = analyze_frame(
        task,
        trajectory.initial,
        friction=trajectory.friction,
        drive=trajectory.drive,
        seed=seed,
        config=AnalyzerConfig(expansions=40, analysis_model=model),
        simulator=simulator,
    )
    return scores, field, simulator


@pytest.mark.parametrize("seed", [0, 1])
def test_pruned_and_full_models_give_the_same_scores_to_the_last_bit(arm_task, seed: int) -> None:  # type: ignore[no-untyped-def]
    full, full_field, full_simulator = _scores(arm_task, "full", seed)
    pruned, pruned_field, pruned_simulator = _scores(arm_task, "pruned", seed)
    assert full_simulator.pruned_contacts is None
    report = pruned_simulator.pruned_contacts
    assert report.applied and report.robot_geoms == 3 and not report.robot_still
    assert (pruned.capture_score, pruned.success_score) == (full.capture_score, full.success_score)
    assert (pruned.nodes, pruned.rejected, pruned.diverged) == (full.nodes, full.rejected, full.diverged)
    # Every tree state: the box's positions and the energy costs, to the last bit.
    np.testing.assert_array_equal(pruned_field.object_pos, full_field.object_pos)
    np.testing.assert_array_equal(pruned_field.costs, full_field.costs)
    assert np.ptp(full_field.object_pos[:, 0, :2]) > 0.01  # the perturbations moved the box


def test_a_pruned_simulator_is_refused_for_the_full_model(arm_task) -> None:  # type: ignore[no-untyped-def]
    task, trajectory = arm_task
    _, _, simulator = _scores(arm_task, "pruned", 0)
    with pytest.raises(InvalidParameterError, match="simulator"):
        analyze_frame(
            task,
            trajectory.initial,
            friction=trajectory.friction,
            drive=trajectory.drive,
            seed=0,
            config=AnalyzerConfig(expansions=5, analysis_model="full"),
            simulator=simulator,
        )


def test_the_command_line_chooses_the_model() -> None:
    import argparse

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert analyzer_config(parser.parse_args(["data"])).analysis_model == "pruned"
    assert analyzer_config(parser.parse_args(["data", "--analysis-model", "full"])).analysis_model == "full"
    with pytest.raises(InvalidParameterError, match="analysis_model"):
        AnalyzerConfig(analysis_model="half")
