"""Resident memory while one process analyses many frames.

Each measurement runs in a fresh interpreter: in the test process, memory freed by earlier tests
would absorb new allocations and hide growth.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from energy_margin.data.generate import generate_dataset

LIMIT_MB = 20.0
FRAMES = 1000
SAMPLE_AT = 200

_MEASURE = textwrap.dedent(
    """
    import json, os, sys
    from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer
    from energy_margin.data.dataset import load_dataset

    path, order, frames, sample_at = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])

    def rss():
        with open("/proc/self/statm") as stream:
            return int(stream.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

    dataset = load_dataset(path)
    analyzer = FrameAnalyzer(dataset, AnalyzerConfig(expansions=20), seed=0)
    total = dataset.n_trajectories * dataset.n_frames
    # "all": every frame once, trajectory by trajectory; "first10": the first 10 trajectories over and over.
    indices = range(frames) if order == "all" else [i % (10 * dataset.n_frames) for i in range(frames)]
    samples = {}
    for count, index in enumerate(indices, start=1):
        row = analyzer(index % total)
        assert 0.0 <= row["capture_score"] <= 1.0
        if count in (sample_at, frames):
            samples[count] = rss()
    print(json.dumps({"growth_mb": (samples[frames] - samples[sample_at]) / 2**20,
                      "simulators": len(analyzer._simulators)}))
    """
)


@pytest.fixture(scope="module")
def many_frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One object, 100 trajectories x 10 frames: 1000 frames of 100 distinct scenes."""
    out = tmp_path_factory.mktemp("memory") / "data"
    generate_dataset("pushing", n_objects=1, n_trajectories=100, n_frames=10, seed=0, out=out)
    return out


def _measure(path: Path, order: str) -> dict[str, float]:
    done = subprocess.run(
        [sys.executable, "-c", _MEASURE, str(path), order, str(FRAMES), str(SAMPLE_AT)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.splitlines()[-1])
    print(f"{order}: RSS growth between frame {SAMPLE_AT} and frame {FRAMES}: {result['growth_mb']:.1f} MB")
    return result


@pytest.mark.slow
def test_no_growth_per_frame(many_frames: Path) -> None:
    """1000 analyses cycling over the first 10 trajectories: the simulator cache stays bounded."""
    result = _measure(many_frames, "first10")
    assert result["simulators"] <= 4
    assert result["growth_mb"] < LIMIT_MB


@pytest.mark.slow
def test_rss_stays_flat_over_1000_frames(many_frames: Path) -> None:
    """Every frame of 100 trajectories x 10 frames once, in the order analyze uses."""
    assert _measure(many_frames, "all")["growth_mb"] < LIMIT_MB
