"""``record --format robomimic``: robomimic / robosuite demonstration files (HDF5) become a dataset."""

from __future__ import annotations

import hashlib
import json
import re
import struct
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.robomimic import reroot_assets
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError

h5py = pytest.importorskip("h5py")

# Two free cubes on a plane, a pusher on a slide joint driven by a position actuator, a goal site.
MODEL = """<mujoco model="pusher_demo">
  <option timestep="0.01"/>
  <default><geom friction="0.5"/></default>
  <asset>MESH_ASSET</asset>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <site name="goal" pos="0 0.24 0.025"/>
    <body name="pusher" pos="0 -0.12 0.035">
      <joint name="push" type="slide" axis="0 1 0" damping="20"/>
      <geom type="box" size="0.12 0.02 0.03" mass="1"/>
    </body>
    <body name="cube_a" pos="-0.05 0 0.025"><freejoint/><geom type="box" size="0.025 0.025 0.025" mass="0.1"/></body>
    <body name="cube_b" pos="0.05 0 0.025"><freejoint/>CUBE_B_GEOM</body>
  </worldbody>
  <actuator><position name="push" joint="push" kp="100"/></actuator>
</mujoco>
"""
BOX_GEOM = '<geom type="box" size="0.025 0.025 0.025" mass="0.1"/>'


def model_xml(mesh_file: str | None = None) -> str:
    """The tiny model; with ``mesh_file``, cube_b is a tetrahedron mesh read from that file."""
    if mesh_file is None:
        return MODEL.replace("<asset>MESH_ASSET</asset>", "").replace("CUBE_B_GEOM", BOX_GEOM)
    asset = f'<asset><mesh name="tet" file="{mesh_file}"/></asset>'
    geom = '<geom type="mesh" mesh="tet" mass="0.1" pos="0 0 -0.025"/>'
    return MODEL.replace("<asset>MESH_ASSET</asset>", asset).replace("CUBE_B_GEOM", geom)


# The capture set: both cubes 0.01-0.09 m in front of the pusher; success: both near the goal.
CAPTURE = {"type": "box", "body": "pusher", "center": [0.0, 0.05, 0.0], "half_size": [0.2, 0.04, 0.1]}
SUCCESS = {"type": "distance", "site": "goal", "max": 0.1}
REGION_ARGS = ["--object-bodies", "cube_*", "--capture", json.dumps(CAPTURE), "--success", json.dumps(SUCCESS)]
ROWS = 60


def simulate(xml: str, reach: float, *, rows: int = ROWS) -> np.ndarray:
    """Run the model with the pusher's target ramped to ``reach``; the states [time, qpos, qvel] of every step."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    states = []
    for step in range(rows):
        data.ctrl[0] = reach * min(1.0, step / 50)
        states.append(np.concatenate([[data.time], data.qpos, data.qvel]))
        mujoco.mj_step(model, data)
    return np.array(states)


def write_demos(
    path: Path,
    demos: dict[str, np.ndarray],
    *,
    xml: str | dict[str, str] | None = None,
    env_args: dict[str, Any] | None = None,
) -> Path:
    """A file in robomimic's layout: data/KEY/states, actions and the attribute model_file."""
    with h5py.File(path, "w") as handle:
        data = handle.create_group("data")
        data.attrs["total"] = sum(len(states) for states in demos.values())
        if env_args is not None:
            data.attrs["env_args"] = json.dumps(env_args)
        for key, states in demos.items():
            group = data.create_group(key)
            group["states"] = states
            group["actions"] = np.zeros((len(states), 7))
            text = xml.get(key, model_xml()) if isinstance(xml, dict) else (xml or model_xml())
            group.attrs["model_file"] = text
    return path


@pytest.fixture(scope="module")
def demo_states() -> dict[str, np.ndarray]:
    """Three demonstrations, keyed so that text order differs from number order."""
    xml = model_xml()
    return {"demo_0": simulate(xml, 0.4), "demo_10": simulate(xml, 0.35), "demo_2": simulate(xml, 0.15)}


def nearest_rows(time: np.ndarray, count: int) -> list[int]:
    return [int(np.argmin(np.abs(time - target))) for target in np.linspace(time[0], time[-1], count)]


def expected_labels(states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Capture and success of every row, from the states (cube origins at qpos 1:4 and 8:11)."""
    pusher = np.stack([np.zeros(len(states)), -0.12 + states[:, 1], np.full(len(states), 0.035)], axis=1)
    cubes = np.stack([states[:, 2:5], states[:, 9:12]], axis=1)
    relative = cubes - pusher[:, None] - np.array(CAPTURE["center"])
    captured = np.all(np.abs(relative) <= np.array(CAPTURE["half_size"]), axis=(1, 2))
    distance = np.linalg.norm(cubes - np.array([0.0, 0.24, 0.025]), axis=2)
    return captured, np.all(distance <= SUCCESS["max"], axis=1)


def test_a_robomimic_file_becomes_a_dataset_that_analyze_and_check_accept(
    tmp_path: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    from energy_margin import AnalyzerConfig, analyze

    path = write_demos(tmp_path / "demos.hdf5", demo_states)
    out = tmp_path / "dataset"
    argv = ["record", "--format", "robomimic", str(path), *REGION_ARGS, "--frames", "4", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr()
    assert "dataset" in printed.out
    assert printed.err.count("\n") == 1 and "follows each demonstration's recorded joint path" in printed.err
    dataset = load_dataset(out)
    assert dataset.task.loaded.spec.motion.robot == "recorded"
    assert dataset.task.make_simulator(2, dataset.task.default_friction(), dataset.arrays["drive"][0]).coasting
    keys = ["demo_0", "demo_2", "demo_10"]
    assert dataset.n_trajectories == 3 and dataset.n_frames == 4 and dataset.n_objects == 2
    for index, key in enumerate(keys):
        states = demo_states[key]
        rows = nearest_rows(states[:, 0], 4)
        np.testing.assert_array_equal(dataset.arrays["frame_time"][index], states[rows, 0])
        np.testing.assert_allclose(dataset.arrays["object_pos"][index, :, 0], states[rows, 2:5])
        np.testing.assert_allclose(dataset.arrays["object_quat"][index, :, 1], states[rows, 12:16])
        np.testing.assert_allclose(dataset.arrays["object_vel"][index, :, 0, :3], states[rows, 17:20])
        np.testing.assert_allclose(dataset.arrays["robot_q"][index, :, 0], states[rows, 1])
        np.testing.assert_allclose(dataset.arrays["robot_v"][index, :, 0], states[rows, 16])
        captured, in_success = expected_labels(states[rows])
        np.testing.assert_array_equal(dataset.arrays["captured"][index], captured)
        np.testing.assert_array_equal(dataset.arrays["in_success"][index], in_success)
    assert dataset.arrays["captured"].any() and not dataset.arrays["captured"].all()
    assert dataset.success_labels().tolist() == [True, False, True]
    (source,) = dataset.metadata["recorded_from"]
    assert source == {
        "file": "demos.hdf5",
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "format": "robomimic",
        "demos": keys,
    }
    assert dataset.metadata["task_config"]["scene_file"] == str(out.resolve() / "source" / "scene.toml")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert main(["check", str(out)]) == 0
    analyze(out, AnalyzerConfig(expansions=10), seed=0, progress=False)
    assert len(load_scores(out)["capture_score"]) == 12


def test_a_scene_file_gives_the_objects_and_sets_and_its_model_is_not_read(
    tmp_path: Path, demo_states: dict[str, np.ndarray]
) -> None:
    path = write_demos(tmp_path / "demos.hdf5", {"demo_0": demo_states["demo_0"]})
    scene = tmp_path / "scene.toml"
    scene.write_text(
        'schema_version = 1\nmjcf = "nowhere.xml"\n\n[objects]\nbodies = ["cube_a", "cube_b"]\n\n'
        "[perturbation]\nlinear_acceleration = [1.0, 1.0, 0.0]\n\n[capture]\n"
        'region = { type = "box", body = "pusher", center = [0.0, 0.05, 0.0], half_size = [0.2, 0.04, 0.1] }\n\n'
        '[success]\nregion = { type = "distance", site = "goal", max = 0.1 }\nat_least = 1\n'
    )
    out = tmp_path / "dataset"
    assert main(["record", "--format", "robomimic", str(path), "--scene", str(scene), "--out", str(out)]) == 0
    written = (out / "source" / "scene.toml").read_text()
    assert "linear_acceleration = [1.0, 1.0, 0.0]" in written and "at_least = 1" in written
    assert main(["check", str(out)]) == 0


def test_states_without_the_time_take_it_from_dt_or_the_control_frequency(
    tmp_path: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    states = demo_states["demo_0"][:, 1:]
    path = write_demos(tmp_path / "demos.hdf5", {"demo_0": states})
    out = tmp_path / "with_dt"
    assert main(["record", "--format", "robomimic", str(path), *REGION_ARGS, "--dt", "0.05", "--out", str(out)]) == 0
    rows = nearest_rows(np.arange(ROWS) * 0.05, 10)
    np.testing.assert_allclose(load_dataset(out).arrays["frame_time"][0], np.array(rows) * 0.05)
    np.testing.assert_allclose(load_dataset(out).arrays["object_pos"][0, :, 1], states[rows, 8:11])
    env_args = {"env_name": "Lift", "type": 1, "env_kwargs": {"control_freq": 20}}
    path = write_demos(tmp_path / "with_env.hdf5", {"demo_0": states}, env_args=env_args)
    out = tmp_path / "from_env"
    assert main(["record", "--format", "robomimic", str(path), *REGION_ARGS, "--out", str(out)]) == 0
    np.testing.assert_allclose(load_dataset(out).arrays["frame_time"][0], np.array(rows) * 0.05)


def tetrahedron_stl(path: Path, size: float = 0.05) -> Path:
    """A binary STL of a tetrahedron with edges ``size`` along the axes, outward normals."""
    vertices = np.array([[0, 0, 0], [size, 0, 0], [0, size, 0], [0, 0, size]], dtype=float) - size / 4
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as stream:
        stream.write(b"\0" * 80 + struct.pack("<I", len(faces)))
        for face in faces:
            stream.write(struct.pack("<3f", 0.0, 0.0, 0.0))
            for vertex in face:
                stream.write(struct.pack("<3f", *vertices[vertex]))
            stream.write(b"\0\0")
    return path


def test_mesh_paths_of_another_machine_are_re_rooted_under_assets(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assets = tmp_path / "assets"
    mesh = tetrahedron_stl(assets / "meshes" / "tet.stl")
    recorded_path = "/home/someone/robosuite/robosuite/models/assets/meshes/tet.stl"
    here = model_xml(str(mesh))
    path = write_demos(tmp_path / "demos.hdf5", {"demo_0": simulate(here, 0.4, rows=20)}, xml=model_xml(recorded_path))
    out = tmp_path / "dataset"
    argv = ["record", "--format", "robomimic", str(path), *REGION_ARGS, "--frames", "3", "--out", str(out)]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and f"{path}:/data/demo_0: model_file: mesh file {recorded_path} does not" in error
    assert not out.exists()
    assert main([*argv, "--assets", str(assets)]) == 0
    assert str(mesh.resolve()) in (out / "source" / "model.xml").read_text()
    assert main(["check", str(out)]) == 0
    # A path under models/assets/ of another install, or only the file's name, is found too.
    other = reroot_assets(model_xml("C:\\robosuite\\models\\assets\\meshes\\tet.stl"), where="x", assets=assets)
    assert str(mesh.resolve()) in other
    flat = tmp_path / "flat"
    tetrahedron_stl(flat / "tet.stl")
    assert str((flat / "tet.stl").resolve()) in reroot_assets(model_xml(recorded_path), where="x", assets=flat)
    with pytest.raises(EnergyMarginError, match=re.escape("x: model_file: mesh file /elsewhere/tet.stl does not")):
        reroot_assets(model_xml("/elsewhere/tet.stl"), where="x", assets=tmp_path / "empty")


def test_an_installed_robosuite_gives_its_assets_without_being_imported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    package = tmp_path / "site" / "robosuite"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("raise RuntimeError('robosuite must not be imported')\n")
    mesh = tetrahedron_stl(package / "models" / "assets" / "meshes" / "tet.stl")
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    recorded = model_xml("/home/someone/robosuite/robosuite/models/assets/meshes/tet.stl")
    assert str(mesh.resolve()) in reroot_assets(recorded, where="x")
    assert "robosuite" not in sys.modules


def _edit(group_name: str, edit: Callable[[Any], None]) -> Callable[[Any], None]:
    def apply(handle: Any) -> None:
        edit(handle[group_name])

    return apply


def _replace_states(value: Callable[[np.ndarray], np.ndarray]) -> Callable[[Any], None]:
    def apply(group: Any) -> None:
        states = value(np.asarray(group["states"][()]))
        del group["states"]
        group["states"] = states

    return apply


def _short_actions(group: Any) -> None:
    del group["actions"]
    group["actions"] = np.zeros((3, 7))


def _set_nan(states: np.ndarray) -> np.ndarray:
    states[7, 3] = np.nan
    return states


BROKEN_XML = model_xml().replace('size="0.12 0.02 0.03"', 'size="0 0.02 0.03"')
OTHER_XML = model_xml().replace('mass="1"', 'mass="2"')
BAD_FILES: dict[str, tuple[Callable[[Any], None], str]] = {
    "no data group": (lambda h: h.move("data", "other"), "demos.hdf5: has no group 'data'"),
    "no demos": (lambda h: [h["data"].move(k, f"run_{k}") for k in list(h["data"])], "/data: holds no demonstration"),
    "no states": (_edit("data/demo_1", lambda g: g.__delitem__("states")), "/data/demo_1: has no dataset 'states'"),
    "no model_file": (
        _edit("data/demo_1", lambda g: g.attrs.__delitem__("model_file")),
        "/data/demo_1: has no attribute 'model_file'",
    ),
    "width": (
        _edit("data/demo_1", _replace_states(lambda s: s[:, :-2])),
        "/data/demo_1: states: has 27 columns, expected 1 + nq + nv = 29 (time, qpos, qvel) or nq + nv = 28",
    ),
    "nan": (_edit("data/demo_1", _replace_states(_set_nan)), "/data/demo_1: states: NaN or infinite value at row 7"),
    "time": (
        _edit("data/demo_1", _replace_states(lambda s: np.concatenate([s[:1], s[:-1]]))),
        "/data/demo_1: states: the time (column 0) does not increase at row 1 (0.0 after 0.0)",
    ),
    "actions": (
        _edit("data/demo_1", _short_actions),
        "/data/demo_1: actions: has 3 rows, states 60",
    ),
    "does not compile": (
        _edit("data/demo_1", lambda g: g.attrs.__setitem__("model_file", BROKEN_XML)),
        "/data/demo_1: model_file: does not compile: Error: size 0 must be positive in geom",
    ),
    "another model": (
        _edit("data/demo_1", lambda g: g.attrs.__setitem__("model_file", OTHER_XML)),
        "/data/demo_1: model_file: compiles to another model than demo_0",
    ),
    "no time and no dt": (
        _edit("data/demo_1", _replace_states(lambda s: s[:, 1:])),
        "/data/demo_1: states: has 28 columns, nq + nv (15 + 13) without the time",
    ),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_bad_files_are_one_line_and_write_nothing(
    tmp_path: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str], case: str
) -> None:
    edit, fragment = BAD_FILES[case]
    path = write_demos(tmp_path / "demos.hdf5", {"demo_0": demo_states["demo_0"], "demo_1": demo_states["demo_2"]})
    with h5py.File(path, "a") as handle:
        edit(handle)
    out = tmp_path / "dataset"
    assert main(["record", "--format", "robomimic", str(path), *REGION_ARGS, "--frames", "3", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and fragment in error, error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos.hdf5"]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--object-bodies", "cube_*", "--capture", "{box", "--success", "{}"], "--capture: '{box' is not valid JSON"),
        (["--object-bodies", "cube_*", "--capture", json.dumps(CAPTURE)], "--success is needed without a scene file"),
        (["--object-bodies", "crate", *REGION_ARGS[2:]], "objects.bodies: no body 'crate' in demos.hdf5"),
        ([*REGION_ARGS, "--frames", "61"], "/data/demo_0: states: has 60 rows, fewer than --frames 61"),
    ],
)
def test_bad_options_are_one_line(
    tmp_path: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str], args: list[str], fragment
) -> None:
    path = write_demos(tmp_path / "demos.hdf5", {"demo_0": demo_states["demo_0"]})
    out = tmp_path / "dataset"
    assert main(["record", "--format", "robomimic", str(path), *args, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and fragment in error, error
    assert not out.exists()


def test_record_without_the_robomimic_format_needs_a_scene_and_points_to_the_format(
    tmp_path: Path, tiny_scene: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_demos(tmp_path / "demos.hdf5", {"demo_0": demo_states["demo_0"]})
    out = str(tmp_path / "dataset")
    assert main(["record", str(path), "--out", out]) == 2
    assert "record needs --scene SCENE.toml" in capsys.readouterr().err
    assert main(["record", "--scene", str(tiny_scene), str(path), "--out", out]) == 2
    assert "pass --format robomimic" in capsys.readouterr().err
    assert main(["record", "--scene", str(tiny_scene), str(path), "--dt", "0.1", "--out", out]) == 2
    assert "--dt applies to --format robomimic only" in capsys.readouterr().err


@pytest.mark.parametrize(("robot", "said"), [("still", "robot is held still"), ("coasting", "keeps each frame's")])
def test_robot_still_or_coasting_is_written_into_the_datasets_scene_and_said(
    tmp_path: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str], robot: str, said: str
) -> None:
    path = write_demos(tmp_path / "demos.hdf5", demo_states)
    out = tmp_path / "dataset"
    argv = ["record", "--format", "robomimic", str(path), *REGION_ARGS, "--frames", "3", "--robot", robot]
    assert main([*argv, "--out", str(out)]) == 0
    assert said in capsys.readouterr().err
    assert f'robot = "{robot}"' in (out / "source" / "scene.toml").read_text()
    dataset = load_dataset(out)
    assert dataset.arrays["drive"].shape == (3, 2)  # no path
    simulator = dataset.task.make_simulator(2, 0.5)
    assert (simulator.still, simulator.coasting) == (robot == "still", robot == "coasting")


def test_robot_recorded_carries_each_demonstrations_path_in_its_drive(
    tmp_path: Path, demo_states: dict[str, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    from energy_margin import AnalyzerConfig, analyze

    path = write_demos(tmp_path / "demos.hdf5", demo_states)
    out = tmp_path / "dataset"
    argv = ["record", "--format", "robomimic", str(path), *REGION_ARGS, "--frames", "3"]  # the default: recorded
    assert main([*argv, "--out", str(out)]) == 0
    assert "follows each demonstration's recorded joint path" in capsys.readouterr().err
    assert 'robot = "recorded"' in (out / "source" / "scene.toml").read_text()
    dataset = load_dataset(out)
    points = dataset.task.loaded.spec.motion.path_points
    assert dataset.arrays["drive"].shape == (3, 2 + points * 3)  # one robot joint: the pusher's slide
    for index, key in enumerate(["demo_0", "demo_2", "demo_10"]):
        states = demo_states[key]
        drive = dataset.arrays["drive"][index]
        # Fewer rows than knots (60 < 64): every row is a knot, the last one repeated.
        rows = np.unique(nearest_rows(states[:, 0], points))
        rows = np.concatenate([rows, np.full(points - rows.size, rows[-1])])
        assert rows.size == points and np.unique(rows).size == len(states)
        np.testing.assert_array_equal(drive[2 : 2 + points], states[rows, 0])
        np.testing.assert_array_equal(drive[2 + points : 2 + 2 * points], states[rows, 1])  # the pusher's qpos
    assert dataset.task.make_simulator(2, 0.5, dataset.arrays["drive"][0]).coasting
    assert main(["check", str(out)]) == 0
    analyze(out, AnalyzerConfig(expansions=5), seed=0, progress=False)
    assert len(load_scores(out)["capture_score"]) == 9


def test_robot_is_refused_for_rollout_files_and_bad_values(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from energy_margin.data.robomimic import record_robomimic

    with pytest.raises(SystemExit):
        main(["record", "x.hdf5", "--format", "robomimic", "--robot", "frozen", "--out", str(tmp_path / "a")])
    assert "invalid choice: 'frozen'" in capsys.readouterr().err
    assert main(["record", "x.npz", "--robot", "still", "--out", str(tmp_path / "b")]) != 0
    assert "--robot applies to --format robomimic only" in capsys.readouterr().err
    with pytest.raises(EnergyMarginError, match="robot"):
        record_robomimic(tmp_path / "x.hdf5", n_frames=2, out=tmp_path / "c", robot="frozen")
