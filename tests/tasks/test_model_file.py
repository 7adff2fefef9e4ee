"""A scene file naming a compiled model (``.mjb``): loaded as it is, the same pipeline, edits refused in one line."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin import compat
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks.model_file import model_differences, save_binary_model
from energy_margin.tasks.scene_model import load_scene, model_hash
from tiny_scene import TINY_SCENE, write_tiny_scene


def _binary_scene(directory: Path, scene: str = TINY_SCENE) -> Path:
    """The tiny scene with its model compiled in code and saved as ``model.mjb``; the scene file names it."""
    xml_scene = write_tiny_scene(directory)
    model = mujoco.MjSpec.from_file(str(directory / "model.xml")).compile()
    save_binary_model(model, directory / "model.mjb")
    path = directory / "binary.toml"
    path.write_text(scene.replace('mjcf = "model.xml"', 'mjcf = "model.mjb"'))
    assert xml_scene.is_file()
    return path


def test_a_binary_model_loads_as_the_same_compiled_model(tmp_path: Path) -> None:
    binary = _binary_scene(tmp_path / "scene")
    loaded, from_xml = load_scene(binary), load_scene(tmp_path / "scene" / "scene.toml")
    assert loaded.spec.mjcf.name == "model.mjb"
    assert loaded.model_sha256 == from_xml.model_sha256 == model_hash(from_xml.model)
    assert loaded.object_names == from_xml.object_names == ("box_a", "box_b")
    np.testing.assert_array_equal(loaded.object_radius, from_xml.object_radius)
    np.testing.assert_array_equal(loaded.motion.mocap_pos, from_xml.motion.mocap_pos)
    # No [design] parameters: a design value given for one is refused as for an MJCF scene.
    with pytest.raises(InvalidParameterError, match="unknown scene configuration keys: width"):
        load_scene(binary, {"width": 0.1})


def test_generate_and_analyze_give_the_same_data_and_scores_as_the_xml(tmp_path: Path, capsys) -> None:
    binary = _binary_scene(tmp_path / "scene")
    xml = tmp_path / "scene" / "scene.toml"
    scores = {}
    for name, scene in (("xml", xml), ("mjb", binary)):
        out = tmp_path / name
        generate = ["generate", "--scene", str(scene), "--trajectories", "1", "--frames", "2", "--seed", "3"]
        assert main([*generate, "--out", str(out)]) == 0
        assert main(["check", str(out)]) == 0
        assert main(["analyze", str(out), "--expansions", "20", "--seed", "4", "--workers", "1"]) == 0
        scores[name] = (load_dataset(out), load_scores(out))
    capsys.readouterr()
    (xml_data, xml_scores), (mjb_data, mjb_scores) = scores["xml"], scores["mjb"]
    assert mjb_data.metadata["task_config"]["model_sha256"] == xml_data.metadata["task_config"]["model_sha256"]
    for name, array in xml_data.arrays.items():
        np.testing.assert_array_equal(mjb_data.arrays[name], array, err_msg=name)
    for column in ("capture_score", "success_score", "nodes", "expansions"):
        np.testing.assert_array_equal(mjb_scores[column], xml_scores[column], err_msg=column)


def test_the_picture_of_a_binary_scene_shows_its_regions_as_the_xml_one(tmp_path: Path, capsys) -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.image

    binary = _binary_scene(tmp_path / "scene")
    pictures = {}
    for name, scene in (("xml", tmp_path / "scene" / "scene.toml"), ("mjb", binary)):
        picture = tmp_path / f"{name}.png"
        assert main(["scene", str(scene), "--picture", str(picture)]) == 0
        pictures[name] = matplotlib.image.imread(picture)[..., :3]
    capsys.readouterr()
    # The regions are drawn over the compiled model from a model of their own: the same picture.
    assert pictures["mjb"].shape == pictures["xml"].shape
    assert float(np.mean(np.abs(pictures["mjb"] - pictures["xml"]))) < 0.01


def _line(text: str, start: str) -> int:
    """The 1-based number of the line of ``text`` that starts with ``start``."""
    return next(number for number, line in enumerate(text.splitlines(), 1) if line.startswith(start))


TEMPLATE_SCENE = TINY_SCENE.replace('bodies = ["box_*"]', 'template = "box_a"\ncount = 2')
DESIGN_SCENE = (
    TINY_SCENE + '\n[design]\nwidth = { geom = "pusher", attribute = "size", index = 0, low = 0.1, high = 0.2 }\n'
)


@pytest.mark.parametrize(
    ("scene", "line", "key", "fragment"),
    [
        (
            TEMPLATE_SCENE,
            _line(TEMPLATE_SCENE, "template ="),
            "objects.template",
            "needs an MJCF model: model.mjb is a compiled model (.mjb)",
        ),
        (
            DESIGN_SCENE,
            _line(DESIGN_SCENE, "width ="),
            "design.width",
            "[design] needs an MJCF model: model.mjb is a compiled model (.mjb)",
        ),
    ],
)
def test_edits_of_a_binary_model_are_refused_in_one_line(
    tmp_path: Path, capsys, scene: str, line: int, key: str, fragment: str
) -> None:
    path = _binary_scene(tmp_path / "scene", scene)
    with pytest.raises(EnergyMarginError) as error:
        load_scene(path)
    message = str(error.value)
    assert message.startswith(f"{path}:{line}: {key}: ") and fragment in message and "\n" not in message
    picture = tmp_path / "p.png"
    assert main(["scene", str(path), "--picture", str(picture)]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not picture.exists()


def _rewrite(path: Path, change: str) -> None:
    data = path.read_bytes()
    if change == "text":
        path.write_text("<mujoco/>\n")
    elif change == "version":
        version = struct.unpack("i", data[12:16])[0]
        path.write_bytes(data[:12] + struct.pack("i", version + 1) + data[16:])
    elif change == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif change == "empty":
        path.write_bytes(b"")


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ("text", r"model\.mjb is not a MuJoCo binary model"),
        ("empty", r"model\.mjb is not a MuJoCo binary model"),
        (
            "version",
            # Before MuJoCo 3.5 the header holds a format number, not the release that wrote it.
            (
                r"model\.mjb was written by MuJoCo \d+\.\d+\.\d+ "
                if compat.mujoco_at_least(compat.MJB_VERSION_SINCE)
                else r"model\.mjb was written by another MuJoCo version or build "
            )
            + r"and this is MuJoCo .*: a binary model is read only by the MuJoCo that wrote it",
        ),
        ("truncated", r"model\.mjb cannot be read as a binary model of MuJoCo .* \(.*\)"),
    ],
)
def test_a_binary_model_this_mujoco_cannot_read_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys, change: str, fragment: str
) -> None:
    path = _binary_scene(tmp_path / "scene")
    _rewrite(path.parent / "model.mjb", change)
    monkeypatch.chdir(tmp_path)
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(EnergyMarginError) as error:
        load_scene(path)
    message = str(error.value)
    assert message.startswith(f"{path}:2: mjcf: ") and re.search(fragment, message), message
    assert "\n" not in message
    assert main(["scene", str(path), "--no-picture"]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and captured.out == "", captured
    # MuJoCo's warnings are kept for the message: no MUJOCO_LOG.TXT, nothing else written.
    assert sorted(tmp_path.rglob("*")) == before


def test_a_missing_binary_model_is_one_line(tmp_path: Path) -> None:
    path = _binary_scene(tmp_path / "scene")
    (path.parent / "model.mjb").unlink()
    with pytest.raises(EnergyMarginError, match=r"binary\.toml:2: mjcf: model file .*model\.mjb does not exist$"):
        load_scene(path)


def test_model_differences_name_sizes_then_fields() -> None:
    spec = mujoco.MjSpec.from_string(
        '<mujoco><worldbody><site name="s"/><body name="b"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    model = spec.compile()
    edited = spec.compile()
    assert model_differences(model, edited) == []
    edited.site_pos[0, 2] += 0.01
    edited.opt.timestep = 0.004
    assert model_differences(model, edited) == ["site_pos", "opt.timestep"]
    spec.worldbody.add_body(name="c")
    assert model_differences(model, spec.compile()) == ["nbody 2 != 3", "nnames 25 != 27"]
