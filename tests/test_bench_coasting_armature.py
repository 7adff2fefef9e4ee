"""benchmarks/coasting_armature.py: each armature's analysis is the package's with that armature."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.cli import main
from energy_margin.data.scores_file import load_scores
from tiny_scene import ARM_OVER_PUCK, ARM_SCENE, write_arm_rollouts, write_tiny_scene

ANALYZE = ("--expansions", "15", "--workers", "1", "--seed", "0", "--no-progress")


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("coasting_armature")


def test_the_package_s_armature_is_still_s_for_still_robots_and_coasting_s_else(bench) -> None:
    assert bench.package_armature("still") == 1e8 and bench.package_armature("coasting") == 1e6


def test_an_armature_s_analysis_is_the_plain_one_at_the_package_s_armature_only(bench, tmp_path: Path) -> None:
    """The copy analysed in a process patched to 1e6 scores as ``analyze`` itself; patched to 1e2 it does not."""
    rollouts = write_arm_rollouts(tmp_path / "rollouts", count=2)
    scene = write_tiny_scene(tmp_path / "scene", scene=ARM_SCENE.replace("ROBOT", 'robot = "coasting"'),
                             model=ARM_OVER_PUCK)  # fmt: skip
    recorded = tmp_path / "recorded"
    assert main(["record", "--scene", str(scene), *map(str, rollouts), "--frames", "8", "--out", str(recorded)]) == 0
    copies = {armature: bench.armature_copy(recorded, tmp_path / f"armature-{armature:g}") for armature in (1e6, 1e2)}
    for armature, directory in copies.items():
        assert json.loads((directory / "dataset.json").read_text())["task_config"]["scene_file"] == str(scene)
        bench.patched_cli(armature)("analyze", directory, *ANALYZE)
    assert main(["analyze", str(recorded), *ANALYZE]) == 0
    plain = load_scores(recorded)
    same, lighter = (load_scores(copies[armature]) for armature in (1e6, 1e2))
    for column in ("capture_score", "success_score"):
        assert same[column].tolist() == plain[column].tolist()
    # A light arm is slowed by the puck it sweeps through: the puck stays nearer its tip.
    assert np.max(np.abs(lighter["capture_score"] - plain["capture_score"])) > 0.01


def test_a_copy_of_a_set_with_its_own_scene_reads_the_copy_s_scene(bench, tmp_path: Path) -> None:
    recorded = tmp_path / "recorded"
    (recorded / "source").mkdir(parents=True)
    (recorded / "source" / "scene.toml").write_text("the scene")
    (recorded / "frames.npz").write_bytes(b"frames")
    document = {"task_config": {"scene_file": "/elsewhere/source/scene.toml"}, "n_frames": 3}
    (recorded / "dataset.json").write_text(json.dumps(document))
    copy = bench.armature_copy(recorded, tmp_path / "copy")
    found = json.loads((copy / "dataset.json").read_text())
    assert found == {"task_config": {"scene_file": str(copy / "source" / "scene.toml")}, "n_frames": 3}
    assert (copy / "source" / "scene.toml").read_text() == "the scene"
    assert (copy / "frames.npz").read_bytes() == b"frames"
    (recorded / "frames.npz").write_bytes(b"changed")
    assert bench.armature_copy(recorded, copy) == copy and (copy / "frames.npz").read_bytes() == b"frames"  # kept


def test_a_row_holds_both_armatures_margins_and_their_paired_difference(bench) -> None:
    def found(cell: str, difference: float | None) -> dict:
        change = {"difference": difference, "low": -0.1, "high": 0.2, "word": "level"}
        return {"questions": {"capture": {"cell": cell}}, "against_package": {"capture": change}}

    entry = {
        "robot": "coasting",
        "package_armature": 1e6,
        "armatures": {"1e+08": found("0.9", 0.05), "1e+06": found("0.8", 0.0)},
    }
    rows = bench.comparison_rows("demos_coasting", entry)
    assert rows == [
        {"set": "demos_coasting", "robot": "coasting", "question": "capture", "package_armature": 1e6,
         "package_margin": "0.8", "armature": 1e8, "margin": "0.9", "difference": 0.05, "low": -0.1, "high": 0.2,
         "word": "level"}
    ]  # fmt: skip


def test_the_benchmark_compares_each_armature_with_the_package_s_on_the_same_set(
    bench, tmp_path: Path, monkeypatch
) -> None:
    """The whole run on a tiny recorded set: every armature analysed (the package's too, though it sorts
    after the other), each row against the package's."""
    import sys

    rollouts = write_arm_rollouts(tmp_path / "rollouts", count=4)
    scene = write_tiny_scene(tmp_path / "scene", scene=ARM_SCENE.replace("ROBOT", 'robot = "coasting"'),
                             model=ARM_OVER_PUCK)  # fmt: skip
    recorded = tmp_path / "work" / "demos_coasting"
    assert main(["record", "--scene", str(scene), *map(str, rollouts), "--frames", "6", "--out", str(recorded)]) == 0
    monkeypatch.setattr(bench, "_sets", lambda work, names, seed: {"demos_coasting": recorded})
    monkeypatch.setattr(sys.modules["robomimic_demos"], "EXPANSIONS", 10)
    out = tmp_path / "armature.json"
    argv = ["coasting_armature.py", "--work", str(tmp_path / "work"), "--out", str(out), "--armatures", "1e8,1e6"]
    monkeypatch.setattr(sys, "argv", argv)
    bench.main()
    document = json.loads(out.read_text())
    entry = document["sets"]["demos_coasting"]
    assert entry["package_armature"] == 1e6 and set(entry["armatures"]) == {"1e+08", "1e+06"}
    assert all(
        (tmp_path / "work" / f"armature-{a}" / "demos_coasting" / "scores.csv").exists() for a in ("1e+08", "1e+06")
    )
    package = entry["armatures"]["1e+06"]
    assert all(change["difference"] in (0.0, None) for change in package["against_package"].values())
    rows = document["rows"]
    assert [row["armature"] for row in rows] == [1e8] * len(package["questions"])
    for row in rows:
        assert row["package_margin"] == package["questions"][row["question"]]["cell"]
        assert row["margin"] == entry["armatures"]["1e+08"]["questions"][row["question"]]["cell"]
