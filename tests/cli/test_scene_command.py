"""``energy-margin scene``: the summary of a scene file and its picture at t = 0 (MuJoCo's renderer)."""

from __future__ import annotations

import re
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
    # The tiny scene leaves at_least out: "every object" is the default.
    assert "capture: every object (default) in box[body=pusher" in out
    assert "success: every object (default) in all(distance[site=goal, max=0.16], height[max=0.1])" in out
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


def test_the_picture_frames_the_objects_and_regions_not_the_whole_model() -> None:
    from energy_margin.report.scene_view import _corners, framed_view

    objects = np.array([[0.0, 0.3, 0.03], [0.1, 0.35, 0.03]])
    region = [_corners(np.array([0.05, 0.5, 0.0]), np.eye(3), np.array([0.1, 0.05, 0.05]))]
    view = framed_view(objects, np.array([0.03, 0.03]), region)
    # Everything framed lies within 0.35 m of the centre; a 3 m arm base or a 10 m floor is not framed.
    assert view.distance < 1.2
    assert 0.0 <= view.lookat[0] <= 0.1 and 0.3 <= view.lookat[1] <= 0.55
    wider = framed_view(objects, np.array([0.03, 0.03]), [*region, _corners(np.zeros(3), np.eye(3), np.full(3, 2.0))])
    assert wider.distance > 3 * view.distance  # a large region is framed
    chosen = framed_view(objects, np.array([0.03, 0.03]), region, camera=(90.0, -30.0, 2.5))
    assert (chosen.azimuth, chosen.elevation, chosen.distance) == (90.0, -30.0, 2.5)


@pytest.mark.parametrize(
    ("camera", "fragment"),
    [
        ("90", "takes AZIMUTH,ELEVATION[,DISTANCE]"),
        ("a,b", "takes AZIMUTH,ELEVATION[,DISTANCE]"),
        ("90,-120", "elevation -120 is outside [-90, 90]"),
        ("90,-30,0", "distance 0 m must be > 0"),
        ("90,-30,nan", "takes AZIMUTH,ELEVATION[,DISTANCE]"),
        # A negative azimuth is the camera's value, not an option (argparse alone would refuse it).
        ("-135,-120", "elevation -120 is outside [-90, 90]"),
    ],
)
def test_a_bad_camera_is_one_line_before_anything_is_printed(
    tiny_scene: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], camera: str, fragment: str
) -> None:
    picture = tmp_path / "p.png"
    assert main(["scene", str(tiny_scene), "--picture", str(picture), "--camera", camera]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and fragment in captured.err
    assert not picture.exists()


def test_the_camera_option_draws_the_picture(tiny_scene: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.image

    pictures = {}
    for name, camera in (("default", None), ("side", "0,-10,1.5")):
        picture = tmp_path / f"{name}.png"
        assert (
            main(["scene", str(tiny_scene), "--picture", str(picture), *(["--camera", camera] if camera else [])]) == 0
        )
        pictures[name] = matplotlib.image.imread(picture)
    assert pictures["default"].shape == pictures["side"].shape
    assert not np.array_equal(pictures["default"], pictures["side"])  # another viewpoint


def test_scene_marks_every_value_that_comes_from_a_default(make_scene, capsys) -> None:
    # Without [perturbation], [bounds] and most optional keys, each value left out says so.
    perturbation = "[perturbation]\nlinear_acceleration = [2.0, 2.0, 0.0]\nangular_acceleration = [0.0, 0.0, 5.0]\n"
    scene = make_scene(replace={perturbation + "max_duration = 0.1\n": ""})
    assert main(["scene", str(scene), "--no-picture"]) == 0
    out = capsys.readouterr().out
    assert (
        "perturbation: linear acceleration (2, 2, 0) m/s^2 (default), angular acceleration (0, 0, 20) rad/s^2 "
        "(default), longest propagation 0.1 s (default), lambda 5 1/J (default)\n"
        "  the default bounds act in the world x-y plane with a torque about z" in out
    )
    assert "objects (2, free (default: read from the model)):" in out
    assert "linear (default) interpolation, duration 1.5 s (150 steps" in out
    assert "command every 0.01 s (default) in analysis" in out
    assert "robot during analysis declared (default)" in out
    assert "friction 0.3-0.6, mass scale 1 (default), time scale 1 (default), start ranges (default) " in out
    assert "x [-0.12, 0.12] m, y [-0.02, 0.08] m, z the model's (default), yaw [-0.3, 0.3] rad" in out
    # Two 6 cm boxes: 2 x 0.0424 m (a corner in x-y), not 2 x 0.052 m (a corner in 3-D).
    assert "min separation 0.0849 m, twice the largest footprint radius, in the x-y plane (default)" in out
    # The band is in the mocap pusher's frame: it follows the robot unless the file says otherwise.
    assert (
        "capture region follows the robot (attached to body 'pusher', moved by mocap body 'pusher') (default)\n" in out
    )
    assert "success region fixed in the world (default)\n" in out
    bounds = next(line for line in out.splitlines() if line.startswith("bounds: "))
    assert re.fullmatch(
        r"bounds: low \(\S+, \S+, \S+\) m \(default: 1 m around the model's geoms\), high \(\S+, \S+, \S+\) m "
        r"\(default: 1 m around the model's geoms\), max speed 10 m/s \(default\); trees reject states outside, "
        r"and no frame outside becomes data",
        bounds,
    )
    width = '\n[design]\nwidth = { geom = "pusher", attribute = "size", index = 0, low = 0.1, high = 0.2 }\n'
    assert main(["scene", str(make_scene(append=width)), "--no-picture"]) == 0
    assert "design width = 0.15 (default: the model's): size[0] of geom 'pusher'" in capsys.readouterr().out
    # Values the file gives carry no mark.
    given = make_scene(
        replace={
            perturbation: perturbation.replace("[2.0, 2.0, 0.0]", "[1.0, 1.0, 0.0]") + "lambda = 7.0\n",
            "[capture]\n": "[capture]\nat_least = 1\nfollow = false\n",
        },
        append="\n[bounds]\nlow = [-1.0, -1.0, -1.0]\nhigh = [1.0, 1.0, 1.0]\nmax_speed = 5.0\n",
    )
    assert main(["scene", str(given), "--no-picture"]) == 0
    out = capsys.readouterr().out
    assert (
        "perturbation: linear acceleration (1, 1, 0) m/s^2, angular acceleration (0, 0, 5) rad/s^2, "
        "longest propagation 0.1 s, lambda 7 1/J\n" in out
    )
    assert "the default bounds" not in out
    assert "capture: at least 1 objects in box[" in out
    assert (
        "; capture region fixed at the analysed frame (follow = false; attached to body 'pusher', moved by mocap "
        "body 'pusher')\n" in out
    )
    assert "bounds: low (-1, -1, -1) m, high (1, 1, 1) m, max speed 5 m/s;" in out
