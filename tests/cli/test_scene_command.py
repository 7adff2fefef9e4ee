"""``energy-margin scene``: the summary of a scene file and its picture at t = 0 (MuJoCo's renderer)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main


def test_scene_prints_what_it_understood_and_draws_it(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    pytest.importorskip("matplotlib")
    picture = tmp_path / "picture.png"
    assert main(["scene", str(tiny_scene), "--picture", str(picture)]) == 0
    out = capsys.readouterr().out
    assert "box_a: mass 0.1 kg" in out and "box_b: mass 0.1 kg" in out
    assert "mocap bodies (1): pusher" in out
    assert "duration 1.5 s (150 steps of 0.01 s)" in out
    assert "force (0.2, 0.2, 0) N" in out  # 0.1 kg x 2 m/s^2
    assert "capture: every object in box[body=pusher" in out
    assert "success: every object in all(distance[site=goal, max=0.16], height[max=0.1])" in out
    import matplotlib.image

    image = matplotlib.image.imread(picture)
    assert image.shape[0] > 500 and image.shape[1] > 700
    # The rendered scene is not blank: many distinct colours.
    assert len(np.unique((image[..., :3] * 255).astype(int).reshape(-1, 3), axis=0)) > 100


def test_scene_with_a_bad_file_is_one_line(make_scene, tmp_path: Path, capsys) -> None:
    scene = make_scene(replace={'bodies = ["box_*"]': 'bodies = ["crate"]'})
    picture = tmp_path / "p.png"
    assert main(["scene", str(scene), "--picture", str(picture)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "objects.bodies: no body 'crate'" in error
    assert not picture.exists()
