"""benchmarks/bench_reference.py says why it cannot run in one line and exits 0."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from bench_modules import load_benchmark

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_reference.py"


def test_a_missing_authors_environment_is_one_skip_line(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--authors-venv", str(tmp_path / "nowhere")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    if (ROOT.parent / "shared" / "reference" / "authors-code").is_dir():
        assert lines == [f"skip: --authors-venv {tmp_path / 'nowhere'} has no bin/python"]
    else:
        assert len(lines) == 1 and lines[0].startswith("skip: the authors' code and frames are not at")


def test_without_the_reference_it_skips(tmp_path: Path) -> None:
    # A copy of the script whose project root has no ../shared beside it.
    root = tmp_path / "project"
    (root / "benchmarks").mkdir(parents=True)
    copy = root / "benchmarks" / "bench_reference.py"
    copy.write_text(SCRIPT.read_text())
    result = subprocess.run([sys.executable, str(copy)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        f"skip: the authors' code and frames are not at {tmp_path / 'shared' / 'reference'} "
        "(../shared/reference from the project root)"
    ]


def test_frame_rows_pair_the_two_sides_frame_by_frame() -> None:
    module = load_benchmark("bench_reference")
    theirs = {
        3: {"runtime_s": 2.0, "capture_score": 0.9, "success_score": 0.1},
        4: {"runtime_s": 3.0, "capture_score": 0.5, "success_score": 0.6},
    }
    ours = {
        4: {"runtime_s": 0.2, "capture_score": 0.4, "success_score": 0.7, "expansions": 150},
        3: {"runtime_s": 0.1, "capture_score": 0.8, "success_score": 0.0, "expansions": 300},
    }
    rows = module.frame_rows(theirs, ours, [3, 4])
    assert [row["frame"] for row in rows] == [3, 4]
    assert rows[0] == {
        "frame": 3,
        "theirs_s": 2.0,
        "ours_s": 0.1,
        "their_capture": 0.9,
        "our_capture": 0.8,
        "their_success": 0.1,
        "our_success": 0.0,
        "our_expansions": 300,
    }
    assert rows[1]["our_expansions"] == 150 and rows[1]["theirs_s"] == 3.0
