from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.robustness.perturb import perturb_dataset, perturb_frame
from energy_margin.runs.versions import engine_versions
from energy_margin.sim import make_simulator
from energy_margin.world.ellipsoid import min_volume_ellipsoid


def _max_penetration(dataset_path: Path) -> float:
    dataset = load_dataset(dataset_path)
    task = dataset.task
    deepest = 0.0
    for t in range(dataset.n_trajectories):
        scene = task.build_scene(dataset.n_objects, float(dataset.arrays["friction"][t]), dataset.arrays["drive"][t])
        simulator = make_simulator(scene)
        for k in range(dataset.n_frames):
            simulator.reset(dataset.frame(t, k))
            deepest = max([deepest, *(depth for _, _, depth in simulator.object_penetrations())])
    return deepest


def test_perturbed_copies_keep_labels_and_zero_velocities(tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "perturbed"
    paths = perturb_dataset(tiny_dataset, repeats=2, seed=3, out=out)
    assert paths == [out / "1", out / "2"]
    true = load_dataset(tiny_dataset)
    for repeat, path in enumerate(paths, start=1):
        copy = load_dataset(path)
        for name in ("captured", "in_success", "robot_q", "robot_v", "friction", "drive", "frame_time"):
            assert np.array_equal(copy.arrays[name], true.arrays[name]), name
        assert np.all(copy.arrays["object_vel"] == 0.0)
        assert np.all(copy.arrays["object_quat"] == [1.0, 0.0, 0.0, 0.0])  # yaw zeroed, as the paper
        assert np.all(np.isfinite(copy.arrays["object_pos"]))
        assert not np.array_equal(copy.arrays["object_pos"], true.arrays["object_pos"])
        info = copy.metadata["perturbation"]
        assert info["repeat"] == repeat and info["seed"] == 3 and info["coordinates"] == "xy"
        # The frames keep the source's versions record; the copy's own is the perturbation's.
        assert copy.metadata["versions"] == true.metadata["versions"]
        assert info["versions"] == engine_versions("mujoco")
        # Upright objects are put on the ground: one common height per frame.
        assert np.ptp(copy.arrays["object_pos"][..., 2], axis=-1).max() < 1e-12
        # No overlaps with each other, the pusher, the ground or the wall.
        assert _max_penetration(path) <= 5e-4 + 1e-9
        # Every object lies inside the (possibly grown) ellipse of the true centres.
        growth = info["largest_growth"]
        for t in range(copy.n_trajectories):
            for k in range(copy.n_frames):
                ellipse = min_volume_ellipsoid(true.arrays["object_pos"][t, k, :, :2], min_thickness=0.05)
                scaled = np.linalg.norm(ellipse.normalized(copy.arrays["object_pos"][t, k, :, :2]), axis=1)
                # Draws come from the fit snapped to 1e-7 m: inside up to that (relative 2e-6).
                assert np.all(scaled <= growth * (1 + 1e-5))
    # The copies differ from each other.
    first, second = (load_dataset(p).arrays["object_pos"] for p in paths)
    assert not np.array_equal(first, second)


@pytest.mark.slow
def test_perturbation_is_deterministic(tiny_dataset: Path, tmp_path: Path) -> None:
    a = perturb_dataset(tiny_dataset, repeats=2, seed=5, out=tmp_path / "a")
    b = perturb_dataset(tiny_dataset, repeats=1, seed=5, out=tmp_path / "b")
    assert np.array_equal(load_dataset(a[0]).arrays["object_pos"], load_dataset(b[0]).arrays["object_pos"])
    c = perturb_dataset(tiny_dataset, repeats=1, seed=6, out=tmp_path / "c")
    assert not np.array_equal(load_dataset(a[0]).arrays["object_pos"], load_dataset(c[0]).arrays["object_pos"])
    # Running again with the same settings keeps the copies; other settings need --overwrite.
    before = (a[0] / "frames.npz").stat().st_mtime_ns
    perturb_dataset(tiny_dataset, repeats=2, seed=5, out=tmp_path / "a")
    assert (a[0] / "frames.npz").stat().st_mtime_ns == before
    with pytest.raises(EnergyMarginError, match="overwrite"):
        perturb_dataset(tiny_dataset, repeats=1, seed=9, out=tmp_path / "a")


def test_keep_orientation(tiny_dataset: Path, tmp_path: Path) -> None:
    path = perturb_dataset(tiny_dataset, repeats=1, seed=0, out=tmp_path / "p", keep_orientation=True)[0]
    assert np.array_equal(load_dataset(path).arrays["object_quat"], load_dataset(tiny_dataset).arrays["object_quat"])


@pytest.mark.slow
def test_scooping_boxes_stay_above_the_table_and_apart(tmp_path: Path) -> None:
    source = tmp_path / "scoop"
    generate_dataset("scooping", n_objects=3, n_trajectories=1, n_frames=3, seed=1, out=source)
    path = perturb_dataset(source, repeats=1, seed=0, out=tmp_path / "p")[0]
    copy = load_dataset(path)
    assert copy.metadata["perturbation"]["coordinates"] == "xyz"
    assert np.all(copy.arrays["object_vel"] == 0.0)
    assert np.all(copy.arrays["object_quat"] == [1.0, 0.0, 0.0, 0.0])  # boxes flat, as the paper
    task = copy.task
    assert np.all(copy.arrays["object_pos"][..., 2] >= task.rest_height - 5e-4)
    assert _max_penetration(path) <= 5e-4 + 1e-9


def test_impossible_placement_is_an_error(make_block_scene, make_resting_frame) -> None:  # type: ignore[no-untyped-def]
    # Two objects at the same spot: their ellipse is a disc of the objects' radius (plus growth),
    # far too small for two 5 cm cylinders with zero tolerance once growth is disabled.
    scene = make_block_scene(2, motion="upright")
    frame = make_resting_frame(scene, spacing=0.0)
    simulator = make_simulator(scene)
    with pytest.raises(EnergyMarginError, match="cannot place"):
        perturb_frame(
            frame,
            simulator,
            np.random.default_rng(0),
            planar=True,
            min_thickness=0.01,
            tolerance=0.0,
            max_attempts=20,
            max_restarts=1,
            max_growth_restarts=0,
        )


def test_cli_perturb(tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "copies"
    assert main(["perturb", str(tiny_dataset), "--repeats", "2", "--seed", "1", "--out", str(out)]) == 0
    assert "2 perturbed copies" in capsys.readouterr().out
    info = json.loads((out / "2" / "dataset.json").read_text())["perturbation"]
    assert info["repeats"] == 2 and info["tolerance_m"] == 5e-4


@pytest.mark.parametrize(
    "args",
    [
        ["perturb", "{missing}", "--out", "{out}"],
        ["perturb", "{data}", "--repeats", "0", "--out", "{out}"],
        ["perturb", "{data}", "--seed", "-1", "--out", "{out}"],
        ["perturb", "{data}", "--out", "{data}"],
        ["perturb", "{data}"],
    ],
)
def test_cli_perturb_bad_input(
    args: list[str], tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    values = {"missing": str(tmp_path / "missing"), "out": str(out), "data": str(tiny_dataset)}
    try:
        status = main([a.format(**values) for a in args])
    except SystemExit as exit_:  # argparse rejects malformed options itself
        status = exit_.code
    assert status != 0
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "error" in err
    assert not out.exists()


def _nudged_fit(relative: float):  # type: ignore[no-untyped-def]
    """``min_volume_ellipsoid`` whose result is scaled by ``1 + relative`` (a rounding-level change)."""
    from energy_margin.world.ellipsoid import Ellipsoid

    def fit(points, **kwargs):  # type: ignore[no-untyped-def]
        exact = min_volume_ellipsoid(points, **kwargs)
        factor = 1.0 + relative
        return Ellipsoid(exact.center * factor, exact.radii * factor, exact.rotation * factor)

    return fit


@pytest.mark.slow
@pytest.mark.parametrize("task", ["pushing", "scooping"])
def test_copies_do_not_change_with_a_rounding_level_change_of_the_fit(
    task: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    source = tmp_path / "source"
    generate_dataset(task, n_objects=3, n_trajectories=2, n_frames=3, seed=2, out=source)
    exact = perturb_dataset(source, repeats=2, seed=1, out=tmp_path / "exact")
    # The nudge is real: drawing from the nudged fit itself moves the points.
    frame = load_dataset(source).frame(0, 0)
    coordinates = frame.object_pos[:, :2] if task == "pushing" else frame.object_pos
    plain = min_volume_ellipsoid(coordinates, min_thickness=0.005)
    nudged = _nudged_fit(1e-12)(coordinates, min_thickness=0.005)
    assert not np.array_equal(plain.sample(np.random.default_rng(0), 5), nudged.sample(np.random.default_rng(0), 5))
    monkeypatch.setattr("energy_margin.robustness.resample.min_volume_ellipsoid", _nudged_fit(1e-12))
    again = perturb_dataset(source, repeats=2, seed=1, out=tmp_path / "nudged")
    for first, second in zip(exact, again, strict=True):
        assert np.array_equal(load_dataset(first).arrays["object_pos"], load_dataset(second).arrays["object_pos"])


@pytest.mark.slow
def test_workers_give_the_same_copies(tiny_dataset: Path, tmp_path: Path) -> None:
    one = perturb_dataset(tiny_dataset, repeats=2, seed=4, out=tmp_path / "one", workers=1)
    two = perturb_dataset(tiny_dataset, repeats=2, seed=4, out=tmp_path / "two", workers=2, progress=True)
    for first, second in zip(one, two, strict=True):
        a, b = load_dataset(first), load_dataset(second)
        for name in ("object_pos", "object_quat", "object_vel"):
            assert np.array_equal(a.arrays[name], b.arrays[name]), name
        assert a.metadata["perturbation"]["candidates"] == b.metadata["perturbation"]["candidates"]


def test_perturb_workers_must_be_positive(tiny_dataset: Path, tmp_path: Path) -> None:
    with pytest.raises(EnergyMarginError, match="workers"):
        perturb_dataset(tiny_dataset, repeats=1, seed=0, out=tmp_path / "p", workers=0)
