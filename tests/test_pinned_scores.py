"""Scores pinned to the values the code gave before the package was regrouped into stages.

A refactor that changes what is computed (a different random stream, another order of physics
calls, a changed label) changes these exact floats. They are exact for one MuJoCo build with one
numpy on one CPU architecture, so they are pinned per release pair in :data:`PINNED`, the one
place that knows them: MuJoCo 4.0.0 with numpy 2 (the newest CI leg) and MuJoCo 3.3.0 with numpy
1.26 (the oldest, ``ci/oldest.txt``; MuJoCo 3.3's contacts move the objects differently, and
numpy 1's sums and norms differ in the last bits). Another pair skips, naming the pairs pinned.
One pushing score differs in its last bit between the x86-64 machines the tests have run on (the
second list of MuJoCo 4.0.0 was measured on an AMD EPYC with AVX2 and no AVX-512); each is pinned
exactly, and a change of the computation moves the scores off both. Pushing is pinned with the
rim ground contacts of that release (``ground_contact="geometry"``, still the default), whatever
the default becomes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

import energy_margin
from energy_margin import AnalyzerConfig
from energy_margin.compat import mujoco_version, numpy_version
from energy_margin.data.scores_file import load_scores

PUSHING_SEEDS = [
    3890642289391122579,
    13194552230369835111,
    11111639471956038763,
    17250117878105928339,
    13663400099114352980,
    9730848019483088636,
    9048968709368590896,
    8740338556333592717,
]
_CAPTURE_4 = [
    0.9990319675841871,
    1.0,
    1.0,
    0.9999999999999997,
    0.9999999999999999,
    0.9999999999999998,
    0.9999999999999999,
    0.9999999999999998,
]
#: Per (MuJoCo release, numpy major version): the pushing capture scores (each list one CPU's),
#: the pushing success scores and the scooping capture scores.
PINNED: dict[tuple[tuple[int, int, int], int], dict[str, list[Any]]] = {
    ((4, 0, 0), 2): {
        # The second list: an AMD EPYC (AVX2, no AVX-512), whose first score differs in its last bit.
        "pushing_capture": [_CAPTURE_4, [0.9990319675841872, *_CAPTURE_4[1:]]],
        "pushing_success": [
            0.0,
            0.0003826021273872315,
            1.0,
            0.9999999999999997,
            0.0,
            0.0,
            0.8556170044439853,
            0.9999999999999998,
        ],
        "scooping_capture": [0.0, 0.04012926724378537, 0.0, 0.0],
    },
    ((3, 3, 0), 1): {
        "pushing_capture": [[0.9990344872661369, 1.0, 1.0, 1.0, 1.0, 1.0, 0.9999999999999999, 1.0]],
        "pushing_success": [0.0, 0.001520292838181316, 1.0, 1.0, 0.0, 0.0, 0.8453752256940691, 1.0],
        "scooping_capture": [0.0, 0.0, 0.0, 0.0],
    },
}


def pinned() -> dict[str, list[Any]]:
    """The pinned scores of the installed MuJoCo and numpy; skips the test for another pair."""
    key = (mujoco_version(), numpy_version()[0])
    if key not in PINNED:
        pairs = ", ".join(f"MuJoCo {'.'.join(map(str, m))} with numpy {n}" for m, n in PINNED)
        pytest.skip(f"scores are pinned for {pairs} only, not MuJoCo {mujoco.__version__} with numpy {np.__version__}")
    return PINNED[key]


@pytest.mark.slow
def test_pushing_scores_are_pinned(tmp_path: Path) -> None:
    expected = pinned()
    out = tmp_path / "push"
    energy_margin.generate_dataset(
        "pushing",
        n_objects=3,
        n_trajectories=2,
        n_frames=4,
        seed=5,
        out=out,
        task_config={"ground_contact": "geometry"},
    )
    energy_margin.analyze(out, AnalyzerConfig(iterations=30, cost="energy"), seed=2, progress=False)
    scores = load_scores(out)
    assert [float(v) for v in scores["capture_score"]] in expected["pushing_capture"]
    assert [float(v) for v in scores["success_score"]] == expected["pushing_success"]
    assert [int(v) for v in scores["seed"]] == PUSHING_SEEDS
    assert set(scores["nodes"].tolist()) == {31}
    assert set(scores["iterations"].tolist()) == {30}


@pytest.mark.slow
def test_scooping_scores_are_pinned(tmp_path: Path) -> None:
    expected = pinned()
    out = tmp_path / "scoop"
    energy_margin.generate_dataset("scooping", n_objects=3, n_trajectories=1, n_frames=4, seed=2, out=out)
    energy_margin.analyze(out, AnalyzerConfig(iterations=15), seed=1, progress=False)
    scores = load_scores(out)
    assert [float(v) for v in scores["capture_score"]] == expected["scooping_capture"]
    assert [float(v) for v in scores["success_score"]] == [0.0] * 4
    assert set(scores["nodes"].tolist()) == {16}
