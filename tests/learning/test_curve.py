from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import InvalidParameterError
from energy_margin.learning.curve import (
    QUESTIONS,
    CurvePoint,
    LearningCurve,
    QuestionAp,
    disagreement,
    frames_needed,
    held_out_trajectories,
    learning_curve,
    select_uncertain,
)
from energy_margin.learning.margin_model import fit_margin_model

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
TINY = {"max_iter": 8}
# 8 trajectories x 6 frames, 2 trajectories held out: a pool of 36 frames.
ACTIVE = {"initial": 4, "ensemble": 3, "ensemble_rounds": 5}
UNCERTAINTY_SIZES = [6, 12, 24, 36]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """A pushing dataset of 3 objects, 8 trajectories x 6 frames, analysed with 8 expansions per frame."""
    out = tmp_path_factory.mktemp("curve") / "push3"
    generate_dataset("pushing", out=out, n_objects=3, n_trajectories=8, n_frames=6, seed=2)
    analyze(out, AnalyzerConfig(expansions=8), seed=0, progress=False)
    return load_dataset(out)


@pytest.fixture(scope="module")
def curves(dataset: Dataset) -> dict[str, LearningCurve]:
    return {
        "random": learning_curve(
            [dataset], kind="boosting", sizes=[4, 15, 36], strategy="random", seed=0, reference=True, **TINY
        ),
        "uncertainty": learning_curve(
            [dataset],
            kind="boosting",
            sizes=UNCERTAINTY_SIZES,
            strategy="uncertainty",
            seed=0,
            batch=4,
            **ACTIVE,
            **TINY,
        ),
    }


def without_seconds(curve: LearningCurve) -> dict[str, Any]:
    out = curve.to_dict(selected=True)
    for point in [*out["points"], out["reference"]]:
        if point is not None:
            point.pop("fit_seconds")
            point.pop("selection_seconds")
    return out


@pytest.mark.parametrize("strategy", ["random", "uncertainty"])
def test_held_out_trajectories_are_never_selected(curves: dict[str, LearningCurve], strategy: str) -> None:
    curve = curves[strategy]
    # fit_margin_model's rule: the first round(0.25 * 8) = 2 of a permutation seeded by seed.
    held = sorted((0, int(t)) for t in np.random.default_rng(0).permutation(8)[:2])
    assert list(curve.held_out) == held
    assert curve.pool_frames == 36 and curve.pool_trajectories == 6 and curve.held_out_frames == 12
    for point in curve.points:
        touched = {(d, t) for d, t, _ in point.selected}
        assert not touched & set(curve.held_out)
        assert len(touched) == point.trajectories


def test_split_and_full_pool_fit_are_fit_margin_models(dataset: Dataset, curves: dict[str, LearningCurve]) -> None:
    # The reference (the whole pool, regressor seed = seed) is the model fit_margin_model fits: the
    # same held-out trajectories, the same training rows in the same order.
    curve = curves["random"]
    assert held_out_trajectories([dataset], seed=0, holdout=0.25) == list(curve.held_out)
    _, report = fit_margin_model([dataset], seed=0, kind="boosting", **TINY)
    reference = curve.reference
    assert reference is not None and reference.frames == report.n_frames["train"] == 36
    assert (reference.r2_capture, reference.r2_success) == (report.r2["capture"], report.r2["success"])
    for question in QUESTIONS:
        assert reference.ap[question] == QuestionAp(**report.ap[question])
    # The last point uses the whole pool too, so it is the same fit.
    assert curve.points[-1].ap == reference.ap


@pytest.mark.parametrize("strategy", ["random", "uncertainty"])
def test_sizes_are_monotone_and_selections_nested(curves: dict[str, LearningCurve], strategy: str) -> None:
    curve = curves[strategy]
    assert [point.frames for point in curve.points] == list(curve.sizes)
    for smaller, larger in zip(curve.points, curve.points[1:], strict=False):
        assert len(set(smaller.selected)) == smaller.frames
        assert set(smaller.selected) < set(larger.selected)
        assert smaller.trajectories <= larger.trajectories
    for point in curve.points:
        assert set(point.ap) == set(QUESTIONS)
        # The tree's AP is measured on the same held-out frames at every size.
        assert {q: point.ap[q].tree for q in QUESTIONS} == {q: curve.points[0].ap[q].tree for q in QUESTIONS}


def test_uncertainty_starts_from_the_random_order_then_departs(
    dataset: Dataset, curves: dict[str, LearningCurve]
) -> None:
    # The initial frames of the uncertainty strategy are the first frames of the random order;
    # the frames it adds next are chosen by the ensemble, not by that order.
    curve = learning_curve([dataset], kind="boosting", sizes=[4, 15], strategy="uncertainty", seed=0, **ACTIVE, **TINY)
    random = curves["random"]
    assert curve.points[0].selected == random.points[0].selected
    assert curve.points[1].selected != random.points[1].selected
    assert curve.points[1].selection_seconds > 0 and curve.points[0].selection_seconds == 0


def test_same_seed_gives_the_same_curve(dataset: Dataset, curves: dict[str, LearningCurve]) -> None:
    again = learning_curve(
        [dataset], kind="boosting", sizes=UNCERTAINTY_SIZES, strategy="uncertainty", seed=0, batch=4, **ACTIVE, **TINY
    )
    assert without_seconds(again) == without_seconds(curves["uncertainty"])
    other = learning_curve(
        [dataset], kind="boosting", sizes=UNCERTAINTY_SIZES, strategy="uncertainty", seed=1, batch=4, **ACTIVE, **TINY
    )
    assert [p.selected for p in other.points[:2]] != [p.selected for p in again.points[:2]]


class SpreadMember:
    """A fake ensemble member: predicts capture = feature 0 times its number, success 0.5."""

    def __init__(self, number: int) -> None:
        self.number = number

    def predict(self, features: np.ndarray) -> np.ndarray:
        return np.stack([features[:, 0] * self.number, np.full(len(features), 0.5)], axis=1)


def test_select_uncertain_takes_the_largest_disagreement() -> None:
    # The members disagree in proportion to feature 0, so the most uncertain candidates are
    # those of the largest feature 0.
    rng = np.random.default_rng(3)
    features = np.stack([rng.permutation(20) / 100.0, rng.normal(size=20)], axis=1)
    targets = rng.uniform(size=(20, 2))
    selected = np.array([0, 1, 2])
    candidates = np.arange(3, 20)
    fitted_rows: list[np.ndarray] = []

    def fit_member(x: np.ndarray, y: np.ndarray, seed: int) -> SpreadMember:
        fitted_rows.append(x)
        return SpreadMember(len(fitted_rows) - 1)

    picked = select_uncertain(features, targets, selected, candidates, 4, members=4, seed=0, fit_member=fit_member)
    expected = candidates[np.argsort(-features[candidates, 0])[:4]]
    np.testing.assert_array_equal(picked, expected)
    # Each member saw only (a bootstrap resample of) the selected frames.
    assert len(fitted_rows) == 4
    for rows in fitted_rows:
        assert all(any(np.array_equal(row, features[i]) for i in selected) for row in rows)

    fitted_rows.clear()
    mixed = select_uncertain(
        features, targets, selected, candidates, 4, members=4, seed=0, random_fraction=0.5, fit_member=fit_member
    )
    np.testing.assert_array_equal(mixed[:2], expected[:2])
    assert set(mixed[2:]) <= set(candidates) - set(expected[:2]) and len(set(mixed)) == 4


def test_disagreement_is_the_summed_member_std() -> None:
    predictions = np.array([[[0.0, 0.2], [0.5, 0.5]], [[1.0, 0.2], [0.5, 0.7]]])  # 2 members, 2 frames
    np.testing.assert_allclose(disagreement(predictions), [0.5, 0.1])
    with pytest.raises(InvalidParameterError, match="predictions"):
        disagreement(np.zeros((2, 3)))


@pytest.mark.parametrize(
    ("arguments", "name"),
    [
        ({"sizes": []}, "sizes"),
        ({"sizes": [4, 4]}, "sizes"),
        ({"sizes": [6, 3]}, "sizes"),
        ({"sizes": [0, 3]}, "sizes"),
        ({"sizes": [4, 37]}, "sizes"),  # the pool holds 36 frames
        ({"strategy": "greedy"}, "strategy"),
        ({"kind": "forest"}, "kind"),
        ({"holdout": 1.0}, "holdout"),
        ({"strategy": "uncertainty", "initial": 0}, "initial"),
        ({"strategy": "uncertainty", "initial": 5}, "initial"),
        ({"strategy": "uncertainty", "ensemble": 1}, "ensemble"),
        ({"strategy": "uncertainty", "random_fraction": 1.5}, "random_fraction"),
        ({"strategy": "uncertainty", "batch": 0}, "batch"),
    ],
)
def test_bad_arguments_raise_naming_the_argument(dataset: Dataset, arguments: dict[str, Any], name: str) -> None:
    settings: dict[str, Any] = {"kind": "boosting", "sizes": [4, 8], "strategy": "random", "seed": 0, **arguments}
    with pytest.raises(InvalidParameterError, match=rf"^{name} ") as raised:
        learning_curve([dataset], **settings)
    assert getattr(raised.value, "parameter", None) == name


def point(frames: int, *aps: float) -> CurvePoint:
    return CurvePoint(
        frames=frames,
        trajectories=1,
        ap={q: QuestionAp(value, 0.9) for q, value in zip(QUESTIONS, aps, strict=True)},
        r2_capture=None,
        r2_success=None,
        fit_seconds=0.0,
        selection_seconds=0.0,
        selected=(),
    )


def test_frames_needed_asks_every_question_and_every_later_size(curves: dict[str, LearningCurve]) -> None:
    reference = point(100, 0.9, 0.8, 0.7, 0.6)
    points = (
        point(10, 0.95, 0.95, 0.95, 0.95),  # within, but the next is not
        point(20, 0.89, 0.79, 0.67, 0.5),  # success_first_half 0.1 short
        point(40, 0.89, 0.79, 0.681, 0.58),  # within 0.02 on every question
        point(80, 0.95, 0.79, 0.69, 0.6),
    )
    curve = curves["random"]
    assert frames_needed(LearningCurve(**{**curve.__dict__, "points": points}), reference) == 40
    assert frames_needed(LearningCurve(**{**curve.__dict__, "points": points}), reference, tolerance=0.1) == 10
    short = (*points[:3], point(80, 0.9, 0.8, 0.7, 0.5))
    assert frames_needed(LearningCurve(**{**curve.__dict__, "points": short}), reference) is None


def test_set_kind_fits_subsets_of_set_inputs(dataset: Dataset) -> None:
    curve = learning_curve(
        [dataset], kind="set", sizes=[6, 9], strategy="uncertainty", seed=0, hidden=8, epochs=3, **ACTIVE
    )
    assert [p.frames for p in curve.points] == [6, 9]
    assert curve.points[-1].fit_seconds > 0 and set(curve.points[-1].ap) == set(QUESTIONS)
