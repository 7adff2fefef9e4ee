"""A scene file end to end: generate, check, analyze (1 and 2 workers), evaluate; a changed model is refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores


def _generate(scene: Path, out: Path, seed: int = 0) -> int:
    return main(
        [
            "generate",
            "--scene",
            str(scene),
            "--trajectories",
            "3",
            "--frames",
            "3",
            "--seed",
            str(seed),
            "--out",
            str(out),
        ]
    )


def test_scene_file_generate_check_analyze_evaluate(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    assert _generate(tiny_scene, one) == 0
    assert _generate(tiny_scene, two) == 0
    capsys.readouterr()
    dataset = load_dataset(one)
    config = dataset.metadata["task_config"]
    assert dataset.metadata["task"] == "scene"
    assert config["scene_file"] == str(tiny_scene.resolve())
    assert len(config["model_sha256"]) == 64 and len(config["scene_sha256"]) == 64
    # Same seed, same dataset.
    for name, array in dataset.arrays.items():
        np.testing.assert_array_equal(array, load_dataset(two).arrays[name], err_msg=name)
    # The pusher pushed the boxes forward, and the labels come from the declared sets.
    pos = dataset.arrays["object_pos"]
    assert np.all(pos[:, -1, :, 1] > pos[:, 0, :, 1] + 0.2)
    assert dataset.arrays["captured"].any()
    assert main(["check", str(one)]) == 0
    common = ["--expansions", "30", "--seed", "4"]
    assert main(["analyze", str(one), "--workers", "1", *common]) == 0
    assert main(["analyze", str(two), "--workers", "2", *common]) == 0
    first, second = load_scores(one), load_scores(two)
    for column in ("capture_score", "success_score", "nodes", "expansions", "seed"):
        np.testing.assert_array_equal(first[column], second[column], err_msg=column)
    assert np.all(first["nodes"] > 1)
    assert main(["evaluate", str(one)]) == 0
    out = capsys.readouterr().out
    assert "capture AP, k-hat=0" in out and "positive rate" in out
    assert main(["analyze", str(one), "--engine", "pybullet", "--expansions", "30", "--overwrite"]) == 2
    assert "runs on mujoco, mujoco-warp only, not --engine pybullet" in capsys.readouterr().err


def test_analyze_refuses_a_dataset_whose_model_changed(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "data"
    assert _generate(tiny_scene, out) == 0
    before = (out / "dataset.json").read_text()
    model = tiny_scene.parent / "model.xml"
    model.write_text(model.read_text().replace('mass="0.1"', 'mass="0.2"'))
    capsys.readouterr()
    assert main(["analyze", str(out), "--expansions", "10"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1
    assert "the model of" in error and "changed since these data were made" in error
    assert not (out / "scores.csv").exists() and not (out / "analysis.json").exists()
    assert (out / "dataset.json").read_text() == before
    # An edited scene file is refused as well.
    model.write_text(model.read_text().replace('mass="0.2"', 'mass="0.1"'))
    tiny_scene.write_text(tiny_scene.read_text().replace("max = 0.16", "max = 0.2"))
    assert main(["check", str(out)]) == 2
    assert "changed since these data were made" in capsys.readouterr().out + capsys.readouterr().err
    assert json.loads(before)["task"] == "scene"


def test_perturb_and_budget_work_on_a_scene_dataset(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    data = tmp_path / "data"
    assert _generate(tiny_scene, data) == 0
    copies = tmp_path / "copies"
    argv = ["perturb", str(data), "--repeats", "2", "--seed", "1", "--out", str(copies), "--keep-orientation"]
    assert main(argv) == 0
    copy = load_dataset(copies / "1")
    assert copy.metadata["task_config"]["model_sha256"] == load_dataset(data).metadata["task_config"]["model_sha256"]
    assert main(["budget", str(data), "--expansions", "5", "10", "--methods", "est", "montecarlo"]) == 0
    assert (data / "budget" / "budget.csv").is_file()


def test_render_and_view_work_on_a_scene_dataset(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    pytest.importorskip("imageio")
    pytest.importorskip("plotly")
    data = tmp_path / "data"
    assert _generate(tiny_scene, data) == 0
    assert main(["analyze", str(data), "--expansions", "10"]) == 0
    video, page = tmp_path / "roll.gif", tmp_path / "view.html"
    assert (
        main(["render", str(data), "--trajectory", "0", "--out", str(video), "--width", "160", "--height", "120"]) == 0
    )
    assert main(["view", str(data), "--trajectory", "0", "--frame", "1", "--out", str(page)]) == 0
    assert video.stat().st_size > 1000 and page.stat().st_size > 1000
