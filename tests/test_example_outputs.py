"""Trying an example as its README says leaves the clone as it was: nothing tracked is written over.

The robot examples' READMEs run ``write_model.py`` and ``energy-margin scene ... --picture``; the
pictures checked in beside the scene files (and gym_pusher's checked-in model files) stay as they
are, the pictures go under ``runs/`` and the written models are files git ignores.
"""

from __future__ import annotations

import hashlib
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from energy_margin.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: The examples whose README draws the scene's picture, and the package each one's model comes from.
NEEDS = {
    "fetch": "gymnasium_robotics",
    "gym_pusher": "gymnasium",
    "jaco": "dm_control",
    "panda_tray": "gymnasium_robotics",
    "planar_manipulator": "dm_control",
    "pushing": None,
}


def git(*args: str) -> str:
    """The output of ``git ARGS`` in the repository (skips the test outside a git checkout)."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs the project's git checkout")
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, check=True, text=True).stdout


def tracked(under: str) -> set[str]:
    """The files git tracks under ``under`` (relative to the repository root)."""
    return set(filter(None, git("ls-files", "-z", under).split("\0")))


def readme_commands(folder: Path) -> list[list[str]]:
    """The ``python`` and ``energy-margin`` commands of the README's code blocks, split as the shell does."""
    blocks = re.findall(r"```[a-z]*\n(.*?)```", (folder / "README.md").read_text(encoding="utf-8"), flags=re.S)
    lines = (line for block in blocks for line in block.splitlines())
    return [shlex.split(line) for line in lines if line.startswith(("python ", "energy-margin "))]


def written_paths(command: list[str]) -> list[str]:
    """The paths a command writes through ``--out`` or ``--picture``, or ``scene``'s default picture."""
    paths = []
    for number, argument in enumerate(command):
        for option in ("--out", "--picture"):
            if argument == option:
                paths.append(command[number + 1])
            elif argument.startswith(f"{option}="):
                paths.append(argument.split("=", 1)[1])
    drawn = not {"--no-picture", "--from-gym"} & set(command)
    if command[:2] == ["energy-margin", "scene"] and drawn and not any(a.startswith("--picture") for a in command):
        paths.append(str(Path(command[2]).with_suffix(".png")))  # scene's default: beside the scene file
    return paths


def test_no_example_command_writes_over_a_tracked_file() -> None:
    files = tracked("examples")
    commands = [
        (folder.name, c)
        for folder in sorted(EXAMPLES.iterdir())
        if (folder / "README.md").is_file()
        for c in readme_commands(folder)
    ]
    assert any(command[:2] == ["energy-margin", "scene"] for _, command in commands)
    for name, command in commands:
        for path in written_paths(command):
            path = os.path.normpath(path)
            assert path not in files, (name, shlex.join(command))
            assert not any(file.startswith(f"{path}/") for file in files), (name, shlex.join(command))


def _state(path: Path) -> tuple[str, int]:
    """The file's SHA-256 and modification time."""
    return hashlib.sha256(path.read_bytes()).hexdigest(), path.stat().st_mtime_ns


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(NEEDS))
def test_trying_an_example_writes_over_none_of_its_tracked_files(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    package = NEEDS[name]
    if package is not None:
        pytest.importorskip(package, reason=f"the {name} example's model ships with {package}")
    pytest.importorskip("matplotlib", reason="scene draws its picture with matplotlib")
    files = sorted(tracked(f"examples/{name}"))
    for file in files:  # the example as a fresh clone has it, in a folder of its own
        (tmp_path / file).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / file, tmp_path / file)
    before = {file: _state(tmp_path / file) for file in files}
    status = git("status", "--porcelain", "examples")
    commands = [c for c in readme_commands(EXAMPLES / name) if c[0] == "python" or c[1] == "scene"]
    assert any(command[1] == "scene" for command in commands)
    monkeypatch.chdir(tmp_path)
    for command in commands:
        if command[0] == "python":
            subprocess.run([sys.executable, *command[1:]], check=True)
        else:
            assert main(command[1:]) == 0
    assert (tmp_path / "runs" / "examples" / name / f"{name}.png").is_file()
    # Not written at all (the same bytes written again would still change the file's time).
    assert {file: _state(tmp_path / file) for file in files} == before
    # What the commands wrote beside the scene file (the models with this machine's paths) git ignores.
    written = sorted(str(path.relative_to(tmp_path)) for path in (tmp_path / "examples").rglob("*") if path.is_file())
    new = [file for file in written if file not in before and "__pycache__" not in file]
    if new:
        assert git("check-ignore", "--no-index", *new).split() == new
    assert git("status", "--porcelain", "examples") == status
