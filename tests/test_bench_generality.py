"""benchmarks/bench_generality.py and scene_without_perturbation.py on the tiny scene."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from energy_margin.cli import main
from energy_margin.tasks.scene_model import load_scene

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_row_compares_the_files_derived_and_calibrated_settings(make_scene, tmp_path: Path) -> None:
    # A goal close enough that some trajectories fail (success and capture labels of both classes).
    # The starts' separation as written before it defaulted to the footprint: labels of both kinds.
    scene = make_scene(
        replace={"max = 0.16": "max = 0.1", "yaw = [-0.3, 0.3]": "yaw = [-0.3, 0.3]\nmin_separation = 0.104"}
    )
    derived_toml = tmp_path / "elsewhere" / "derived.toml"
    subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "scene_without_perturbation.py"),
            str(scene),
            str(derived_toml),
            "--derive",
        ],
        check=True,
    )
    derived_text = derived_toml.read_text()
    assert "linear_acceleration" not in derived_text and derived_text.endswith("[perturbation]\nderive = true\n")
    assert f'mjcf = "{scene.parent / "model.xml"}"' in derived_text
    assert set(load_scene(derived_toml).perturbation.derived) == {
        "lambda",
        "max_duration",
        "linear_acceleration",
        "angular_acceleration",
    }
    fixed_toml = derived_toml.with_name("fixed.toml")
    subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "scene_without_perturbation.py"), str(scene), str(fixed_toml)],
        check=True,
    )
    assert load_scene(fixed_toml).perturbation.derived == {}
    for name, toml in (("file", scene), ("derived", derived_toml), ("fixed", fixed_toml)):
        common = ["--trajectories", "10", "--frames", "6", "--seed", "5", "--out", str(tmp_path / name)]
        assert main(["generate", "--scene", str(toml), *common]) == 0
    result = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "bench_generality.py"),
            "tiny",
            str(tmp_path / "file"),
            str(tmp_path / "derived"),
            "--work",
            str(tmp_path / "work"),
            "--resamples",
            "50",
            "--expansions",
            "20",
            "--json",
            str(tmp_path / "row.json"),
            "--variant",
            f"fixed={tmp_path / 'fixed'}",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    row = json.loads((tmp_path / "row.json").read_text())
    settings = [entry["settings"] for entry in row["rows"]]
    assert settings[0].startswith("the file's") and settings[1].startswith("derived") and "by fold" in settings[2]
    assert settings[3] == "fixed (λ 5)"
    for entry in row["rows"]:
        assert set(entry["ap"]) == {
            "capture k̂ = 0",
            "capture k̂ = 2",
            "capture k̂ = 4",
            "success, first 3",
            "success, first 5",
        }
        assert {verdict["word"] for verdict in entry["verdict"].values()} <= {"ahead", "level", "behind", "n/a"}
    assert "| tiny | baseline: distance |" in result.stdout
