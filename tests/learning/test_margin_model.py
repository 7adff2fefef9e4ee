from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin import __version__
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.learning.features import FrameFeatures
from energy_margin.learning.margin_model import (
    MarginModel,
    MarginModelReport,
    fit_margin_model,
    load_margin_model,
    load_training_datasets,
)
from energy_margin.learning.regressors import BoostingRegressor, MlpRegressor
from energy_margin.world.state import FrameState

# Tiny regressors: the tests check the mechanism, not the fit (which then stops before converging).
pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
SMALL = {"mlp": {"hidden": (8,), "max_iter": 40}, "boosting": {"max_iter": 8}, "set": {"hidden": 8, "epochs": 6}}


@pytest.fixture(scope="module")
def analysed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A pushing dataset of 3 objects, 6 trajectories x 3 frames, analysed with 8 expansions per frame."""
    out = tmp_path_factory.mktemp("learn") / "push3"
    generate_dataset("pushing", out=out, n_objects=3, n_trajectories=6, n_frames=3, seed=2)
    analyze(out, AnalyzerConfig(expansions=8), seed=0, progress=False)
    return out


@pytest.fixture(scope="module")
def dataset(analysed: Path) -> Dataset:
    return load_dataset(analysed)


@pytest.fixture(scope="module", params=["mlp", "boosting", "set"])
def fitted(request: pytest.FixtureRequest, dataset: Dataset) -> tuple[MarginModel, MarginModelReport]:
    return fit_margin_model([dataset], seed=0, kind=request.param, **SMALL[request.param])


def frames_of(dataset: Dataset) -> list[FrameState]:
    return [dataset.frame(t, k) for t in range(dataset.n_trajectories) for k in range(dataset.n_frames)]


def test_predict_shapes_range_and_batching(fitted: tuple[MarginModel, MarginModelReport], dataset: Dataset) -> None:
    model, _ = fitted
    frames = frames_of(dataset)
    capture, success = model.predict(dataset.task, frames)
    assert capture.shape == success.shape == (len(frames),)
    assert np.all((capture >= 0) & (capture <= 1)) and np.all((success >= 0) & (success <= 1))
    # One vectorised call gives what one call per frame gives.
    single = np.array([np.concatenate(model.predict(dataset.task, [frame])) for frame in frames])
    # The set network computes in float32, whose sums may round differently in a batch.
    tolerance = 1e-6 if model.kind == "set" else 1e-12
    np.testing.assert_allclose(single, np.stack([capture, success], axis=1), rtol=0, atol=tolerance)
    live = model.score_state(dataset.task, frames[4])
    assert (live.capture, live.success) == pytest.approx((capture[4], success[4]), abs=tolerance)
    assert live.stopped_by == "learned" and live.expansions == 0 and live.seconds > 0


def test_report_splits_by_trajectory(fitted: tuple[MarginModel, MarginModelReport], dataset: Dataset) -> None:
    _, report = fitted
    assert report.n_trajectories == {"train": 4, "held_out": 2}
    assert report.n_frames == {"train": 4 * dataset.n_frames, "held_out": 2 * dataset.n_frames}
    assert set(report.r2) == {"capture", "success"}
    for question in ("capture", "capture_window2", "success", "success_first_half"):
        assert set(report.ap[question]) == {"learned", "tree"}
    assert report.seconds_per_query > 0 and report.tree_seconds_per_frame > 0
    assert report.speedup == pytest.approx(report.tree_seconds_per_frame / report.seconds_per_query)
    assert report.feature_set == ("object-sets/1" if report.kind == "set" else "frame-statistics/1")


def test_save_load_round_trip_predicts_identically(
    fitted: tuple[MarginModel, MarginModelReport], dataset: Dataset, tmp_path: Path
) -> None:
    model, report = fitted
    path = tmp_path / "model"  # no .npz suffix: the file keeps the given name
    model.save(path)
    assert path.is_file() and not list(tmp_path.glob(".*"))
    loaded = load_margin_model(path, task_name="pushing")
    frames = frames_of(dataset)
    for ours, theirs in zip(model.predict(dataset.task, frames), loaded.predict(dataset.task, frames), strict=True):
        np.testing.assert_array_equal(ours, theirs)
    assert (loaded.task_name, loaded.kind, loaded.package_version) == ("pushing", model.kind, __version__)
    assert loaded.task.config == dataset.task.config
    assert loaded.report["r2"] == json.loads(json.dumps(report.r2))


#: The report's keys, in the order of the dictionary earlier releases returned and saved.
REPORT_KEYS = [
    "r2",
    "ap",
    "success_frames",
    "capture_positive_rate",
    "success_positive_rate",
    "seconds_per_query",
    "seconds_single_query",
    "cpu_seconds_per_query",
    "cpu_seconds_single_query",
    "tree_seconds_per_frame",
    "speedup",
    "speedup_single_query",
    "task",
    "kind",
    "seed",
    "holdout",
    "feature_set",
    "n_features",
    "n_trajectories",
    "n_frames",
    "fit_seconds",
    "fit",
    "datasets",
]


def test_the_report_is_typed_and_its_dictionary_is_the_saved_json(
    fitted: tuple[MarginModel, MarginModelReport], tmp_path: Path
) -> None:
    import warnings

    model, report = fitted
    assert isinstance(report, MarginModelReport)
    assert report.task == "pushing" and report.seed == 0 and report.holdout == 0.25 and report.success_frames == 3
    assert list(report.to_dict()) == REPORT_KEYS
    # The model keeps (and saves) the dictionary: the file's report is the one written before.
    assert model.report == report.to_dict() and isinstance(model.report, dict)
    model.save(tmp_path / "model.npz")
    loaded = load_margin_model(tmp_path / "model.npz", task_name="pushing")
    assert loaded.report == json.loads(json.dumps(report.to_dict()))
    assert MarginModelReport.from_dict(report.to_dict()) == report
    # Reading it as the dictionary of earlier releases still works, with a warning naming the attribute.
    with pytest.warns(DeprecationWarning, match=r"use \.n_frames"):
        assert report["n_frames"] == report.n_frames
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "ap" in report and list(report) == REPORT_KEYS and len(report) == len(REPORT_KEYS)


def rewrite_header(path: Path, **changes: object) -> None:
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files}
    header = json.loads(arrays["header"].tobytes())
    header.update(changes)
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with path.open("wb") as stream:
        np.savez(stream, **arrays)


def test_refuses_foreign_task_version_and_files(fitted: tuple[MarginModel, MarginModelReport], tmp_path: Path) -> None:
    model, _ = fitted
    path = tmp_path / "model.npz"
    model.save(path)
    with pytest.raises(EnergyMarginError, match="is a model of task 'pushing', not 'scooping'"):
        load_margin_model(path, task_name="scooping")
    from energy_margin.tasks import get_task

    with pytest.raises(EnergyMarginError, match="fitted on task 'pushing', not 'scooping'"):
        model.predict(get_task("scooping"), [])
    rewrite_header(path, package_version="0.0.1")
    with pytest.raises(EnergyMarginError, match=r"fitted by energy-margin '0.0.1', this is .*learn") as error:
        load_margin_model(path)
    assert "\n" not in str(error.value)
    model.save(path)
    rewrite_header(path, feature_set="frame-statistics/0")
    with pytest.raises(EnergyMarginError, match="uses features 'frame-statistics/0'"):
        load_margin_model(path)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not an archive at all")
    with pytest.raises(EnergyMarginError, match="not a margin model file"):
        load_margin_model(garbage)
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, weights=np.ones(3))
    with pytest.raises(EnergyMarginError, match=r"not a margin model file \(no header\)"):
        load_margin_model(foreign)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, header=np.array([{"a": 1}], dtype=object))
    with pytest.raises(EnergyMarginError, match="not a margin model file"):
        load_margin_model(pickled)
    with pytest.raises(EnergyMarginError, match="does not exist"):
        load_margin_model(tmp_path / "missing.npz")
    model.save(path)
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays = {name: value for name, value in arrays.items() if not name.endswith("_0") and name != "regressor.depth"}
    with path.open("wb") as stream:
        np.savez(stream, **arrays)
    with pytest.raises(EnergyMarginError, match="corrupt"):
        load_margin_model(path)
    # Parameters of another width than the header's feature names.
    model.save(path)
    rewrite_header(path, feature_names=["x"] * 5)
    with pytest.raises(EnergyMarginError, match="corrupt parameters"):
        load_margin_model(path)


def test_features_do_not_depend_on_object_order_or_count(dataset: Dataset) -> None:
    features = FrameFeatures(dataset.task)
    frame = dataset.frame(1, 1)
    order = np.array([2, 0, 1])
    shuffled = FrameState(
        frame.object_pos[order], frame.object_quat[order], frame.object_vel[order], frame.robot_q, frame.robot_v
    )
    np.testing.assert_allclose(features([shuffled]), features([frame]), rtol=1e-12, atol=1e-12)
    fewer = FrameState(frame.object_pos[:2], frame.object_quat[:2], frame.object_vel[:2], frame.robot_q, frame.robot_v)
    both = features([frame, fewer])
    assert both.shape == (2, features.dimension) == (2, len(features.names))
    assert both[1, features.names.index("n_objects")] == 2
    np.testing.assert_array_equal(both[0], features([frame])[0])
    # The pusher's anchor: its x and y are robot_q's first two coordinates.
    dx = features.names.index("dx_mean")
    assert both[0, dx] == pytest.approx(float(np.mean(frame.object_pos[:, 0] - frame.robot_q[0])))


def test_exported_regressors_match_scikit_learn() -> None:
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.neural_network import MLPRegressor
    from sklearn.preprocessing import StandardScaler

    rng = np.random.default_rng(0)
    x = rng.normal(size=(60, 5))
    y = np.stack([np.sin(x[:, 0]), x[:, 1] > 0], axis=1).astype(float)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):  # an oversubscribed OpenMP pool is slow on a shared machine
        models = [HistGradientBoostingRegressor(max_iter=12, random_state=0).fit(x, y[:, i]) for i in range(2)]
    boosting = BoostingRegressor.from_sklearn(models)
    expected = np.stack([model.predict(x) for model in models], axis=1)
    np.testing.assert_allclose(boosting.predict(x), expected, rtol=0, atol=1e-12)
    scaler = StandardScaler().fit(x)
    mlp = MLPRegressor(hidden_layer_sizes=(7, 5), max_iter=30, random_state=0).fit(scaler.transform(x), y)
    np.testing.assert_allclose(
        MlpRegressor.from_sklearn(scaler, mlp).predict(x), mlp.predict(scaler.transform(x)), rtol=0, atol=1e-12
    )


def test_fit_validates_its_arguments(dataset: Dataset) -> None:
    with pytest.raises(InvalidParameterError, match="kind"):
        fit_margin_model([dataset], seed=0, kind="forest")
    with pytest.raises(InvalidParameterError, match="holdout"):
        fit_margin_model([dataset], seed=0, holdout=1.0)
    with pytest.raises(EnergyMarginError, match="at least one"):
        fit_margin_model([], seed=0)


def test_learn_command(analysed: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "push.npz"
    assert main(["learn", str(analysed), "--out", str(out), "--kind", "boosting", "--seed", "1", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["kind"] == "boosting" and report["seed"] == 1 and report["out"] == str(out)
    assert load_margin_model(out, task_name="pushing").kind == "boosting"
    # An existing model is kept unless --overwrite.
    assert main(["learn", str(analysed), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["learn", str(analysed), "--out", str(out), "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert "held-out R²" in text and "learned  tree" in text and "k-hat=2" in text and "per query" in text
    # A dataset of another task, and one without scores, are refused with one line.
    scoop = tmp_path / "scoop"
    generate_dataset("scooping", out=scoop, n_objects=2, n_trajectories=1, n_frames=2, seed=0)
    assert main(["learn", str(analysed), str(scoop), "--out", str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err
    assert "different tasks" in err and err.count("\n") == 1
    assert main(["learn", str(scoop), "--out", str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err
    assert "scores.csv" in err and "analyze" in err and err.count("\n") == 1
    assert not (tmp_path / "m.npz").exists()


def test_load_training_datasets_checks_scores(analysed: Path) -> None:
    assert [d.path for d in load_training_datasets([analysed])] == [analysed]


def test_same_seed_same_model(fitted: tuple[MarginModel, MarginModelReport], dataset: Dataset) -> None:
    model, report = fitted
    again, report_again = fit_margin_model([dataset], seed=0, kind=model.kind, **SMALL[model.kind])
    frames = frames_of(dataset)
    for ours, theirs in zip(model.predict(dataset.task, frames), again.predict(dataset.task, frames), strict=True):
        np.testing.assert_array_equal(ours, theirs)
    assert report_again.r2 == report.r2 and report_again.ap == report.ap


def _read_scores_csv(path: Path, n_trajectories: int, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Capture and success scores of scores.csv as (T, K) grids, read with the csv module."""
    import csv

    capture, success = np.full((n_trajectories, n_frames), np.nan), np.full((n_trajectories, n_frames), np.nan)
    with (path / "scores.csv").open(newline="") as stream:
        for row in csv.DictReader(stream):
            t, k = int(row["trajectory"]), int(row["frame"])
            capture[t, k], success[t, k] = float(row["capture_score"]), float(row["success_score"])
    assert np.isfinite(capture).all() and np.isfinite(success).all()
    return capture, success


def test_held_out_r2_and_ap_match_an_independent_computation(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sklearn.metrics import average_precision_score, r2_score

    from energy_margin.learning import margin_model

    # Ten objects: about half the frames captured, half the trajectories successful (seed 2).
    out = tmp_path / "push10"
    generate_dataset("pushing", out=out, n_objects=10, n_trajectories=8, n_frames=4, seed=2)
    analyze(out, AnalyzerConfig(expansions=8), seed=0, progress=False)
    dataset = load_dataset(out)
    fitted_on: list[tuple[np.ndarray, np.ndarray]] = []
    original = margin_model.fit_regressor

    def spy(kind: str, features: np.ndarray, targets: np.ndarray, **options: object):
        fitted_on.append((features.copy(), targets.copy()))
        return original(kind, features, targets, **options)  # type: ignore[arg-type]

    monkeypatch.setattr(margin_model, "fit_regressor", spy)
    model, report = fit_margin_model([dataset], seed=0, kind="mlp", holdout=0.5, hidden=(16,), max_iter=200)
    model.save(tmp_path / "model.npz")
    loaded = load_margin_model(tmp_path / "model.npz", task_name="pushing")
    ((train_x, train_y),) = fitted_on
    n_traj, n_frames = dataset.n_trajectories, dataset.n_frames
    capture, success = _read_scores_csv(out, n_traj, n_frames)
    # The split is by trajectory: each trajectory's frames are all in the fit or none is.
    features = FrameFeatures(dataset.task)
    fitted_rows = {row.tobytes() for row in train_x}
    held, kept = [], []
    for t in range(n_traj):
        rows = features([dataset.frame(t, k) for k in range(n_frames)])
        inside = [row.tobytes() in fitted_rows for row in rows]
        assert all(inside) or not any(inside), f"trajectory {t} is split"
        (kept if all(inside) else held).append(t)
    assert len(held) == report.n_trajectories["held_out"] == 4 and len(kept) == 4
    assert train_x.shape[0] == len(kept) * n_frames == report.n_frames["train"]
    # The fit's targets are the kept trajectories' scores, frame by frame.
    np.testing.assert_array_equal(train_y, np.stack([capture[kept].ravel(), success[kept].ravel()], axis=1))
    # Held-out predictions of the saved model, and the report's figures computed from them.
    predicted_capture, predicted_success = loaded.predict(
        dataset.task, [dataset.frame(t, k) for t in held for k in range(n_frames)]
    )
    predicted_capture, predicted_success = (
        predicted_capture.reshape(len(held), n_frames),
        predicted_success.reshape(len(held), n_frames),
    )
    assert np.ptp(predicted_capture) > 0.01  # the predictions rank the frames (not one constant)
    assert report.r2["capture"] == pytest.approx(r2_score(capture[held].ravel(), predicted_capture.ravel()), abs=1e-9)
    assert report.r2["success"] == pytest.approx(r2_score(success[held].ravel(), predicted_success.ravel()), abs=1e-9)
    captured = dataset.arrays["captured"][held].astype(bool)
    stays = captured.copy()  # captured at k, k+1 and k+2 (the frames that exist)
    stays[:, :-1] &= captured[:, 1:]
    stays[:, :-2] &= captured[:, 2:]
    succeeded = dataset.arrays["in_success"][held, -1].astype(bool)
    last3 = np.array([0.0, 1.0, 2.0, 3.0]) / 6.0  # linear weights of the last 3 of 4 frames
    first_half = np.array([1.0, 2.0]) / 3.0  # the first 2 frames, linear weights
    expected = {
        "capture": (captured.ravel(), predicted_capture.ravel(), capture[held].ravel()),
        "capture_window2": (stays.ravel(), predicted_capture.ravel(), capture[held].ravel()),
        "success": (succeeded, predicted_success @ last3, success[held] @ last3),
        "success_first_half": (succeeded, predicted_success[:, :2] @ first_half, success[held][:, :2] @ first_half),
    }
    for question, (labels, learned, tree) in expected.items():
        assert 0 < labels.sum() < labels.size, question  # both classes: the AP is defined
        assert report.ap[question]["learned"] == pytest.approx(average_precision_score(labels, learned), abs=1e-9)
        assert report.ap[question]["tree"] == pytest.approx(average_precision_score(labels, tree), abs=1e-9)
