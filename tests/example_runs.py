"""What the example tests share: write an example's scene, generate a quick dataset of it, check, analyse, evaluate.

A module of its own (not ``conftest``), importable by name like ``tiny_scene``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.scores_file import load_scores

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: The generate options of a quick run: 2 trajectories of 3 frames.
QUICK = ["--trajectories", "2", "--frames", "3", "--seed", "0"]


def write_example(name: str, tmp_path: Path) -> Path:
    """Run ``examples/<name>/write_model.py`` into ``tmp_path/<name>``, copy ``<name>.toml`` there, return its path."""
    folder = tmp_path / name
    subprocess.run([sys.executable, str(EXAMPLES / name / "write_model.py"), "--out", str(folder)], check=True)
    scene = folder / f"{name}.toml"
    shutil.copy(EXAMPLES / name / f"{name}.toml", scene)
    return scene


def generate_quick(scene: Path, out: Path) -> Dataset:
    """Generate a quick dataset (``QUICK``) of the scene file ``scene`` into ``out`` and load it."""
    assert main(["generate", "--scene", str(scene), *QUICK, "--out", str(out)]) == 0
    return load_dataset(out)


def analyze_and_evaluate(dataset: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """Check, analyse (every search grew past its root node) and evaluate ``dataset``; return evaluate's output."""
    assert main(["check", str(dataset)]) == 0
    assert main(["analyze", str(dataset), "--expansions", "15", "--workers", "1"]) == 0
    assert load_scores(dataset)["nodes"].min() > 1
    capsys.readouterr()
    assert main(["evaluate", str(dataset)]) == 0
    return capsys.readouterr().out
