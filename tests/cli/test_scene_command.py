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
