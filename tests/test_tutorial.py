"""Every shell command of the tutorial runs: each page's bash blocks, in order, in a fresh folder.

The folder stands for the repository root: it links ``examples/`` and runs ``energy-margin`` and
``python`` with this interpreter. Each page takes a few seconds with the small settings it shows.
"""

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial"
#: The packages a page needs beyond the core ones, with the extra that installs them.
NEEDS = {
    "own-robot.md": {"gymnasium": "gymnasium"},
    "gymnasium.md": {"gymnasium": "gymnasium"},
    "demonstrations.md": {},
}


def bash_blocks(page: Path) -> list[str]:
    return re.findall(r"^```bash\n(.*?)^```", page.read_text(encoding="utf-8"), flags=re.S | re.M)


def test_every_lesson_is_run_here() -> None:
    lessons = {path.name for path in TUTORIAL.glob("*.md") if bash_blocks(path)}
    assert lessons == set(NEEDS)


@pytest.mark.parametrize("name", sorted(NEEDS))
def test_the_lesson_runs(name: str, tmp_path: Path) -> None:
    for module, extra in NEEDS[name].items():
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{name} needs {module}: pip install 'energy-margin[{extra}]'")
    blocks = bash_blocks(TUTORIAL / name)
    assert blocks, f"{name} has no bash block"
    shims = tmp_path / "bin"
    shims.mkdir()
    for command, line in {
        "energy-margin": f'exec "{sys.executable}" -m energy_margin "$@"',
        "python": f'exec "{sys.executable}" "$@"',
    }.items():
        shim = shims / command
        shim.write_text(f"#!/bin/sh\n{line}\n", encoding="utf-8")
        shim.chmod(0o755)
    work = tmp_path / "root"
    work.mkdir()
    (work / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    env = {**os.environ, "PATH": f"{shims}{os.pathsep}{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg"}
    source = str(ROOT / "src")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (source, os.environ.get("PYTHONPATH", "")) if p)
    script = "set -euo pipefail\n" + "\n".join(blocks)
    result = subprocess.run(
        ["bash", "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=300, check=False
    )
    assert result.returncode == 0, f"{name}: exit {result.returncode}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
