"""Every shell command of the tutorial runs: each page's bash blocks, in order, in a fresh folder.

The runner is ``tools/tutorial.py`` (which also times the lessons); each page takes a few seconds
with the small settings it shows.
"""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import tutorial  # noqa: E402

sys.path.remove(str(ROOT / "tools"))


def test_every_lesson_is_run_here() -> None:
    lessons = {path.name for path in tutorial.TUTORIAL.glob("*.md") if tutorial.bash_blocks(path)}
    assert lessons == set(tutorial.LESSONS)


@pytest.mark.parametrize("name", sorted(tutorial.LESSONS))
def test_the_lesson_runs(name: str, tmp_path: Path) -> None:
    for module in tutorial.LESSONS[name]:
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{name} needs {module}: pip install 'energy-margin[{module}]'")
    status, output = tutorial.run_lesson(tutorial.TUTORIAL / name, tmp_path, source=ROOT / "src")
    assert status == 0, f"{name}: exit {status}\n{output}"
