"""The declared ranges, the lock file and the oldest leg's constraints agree.

``pyproject.toml`` declares the range of every dependency; ``requirements.lock`` pins the versions
the quick start and the newest leg install; ``ci/oldest.txt`` pins every declared lower bound for
the oldest leg. A lock or an oldest pin outside its range, or a declared dependency without a pin,
fails here before an install does.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def declared() -> dict[str, Requirement]:
    """Every runtime and extra requirement of pyproject.toml by package name (one range each)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    lines = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        lines.extend(extra)
    requirements: dict[str, Requirement] = {}
    for line in lines:
        requirement = Requirement(line)
        name = canonicalize_name(requirement.name)
        if name in requirements:
            assert requirements[name].specifier == requirement.specifier, f"{name} declared with two ranges"
        requirements[name] = requirement
    return requirements


def pins(path: Path) -> dict[str, Version]:
    """The ``name==version`` lines of a requirements file."""
    found = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        match = re.match(r"^([A-Za-z0-9_.\-]+)==([^\s;#]+)", line)
        if match:
            found[canonicalize_name(match.group(1))] = Version(match.group(2))
    return found


def test_every_dependency_declares_a_range_with_a_lower_and_an_upper_bound() -> None:
    for name, requirement in declared().items():
        operators = {spec.operator for spec in requirement.specifier}
        assert ">=" in operators and "<" in operators, f"{name}: {requirement.specifier} is not a range"


@pytest.mark.parametrize("path", ["requirements.lock", "ci/oldest.txt"])
def test_every_pin_lies_in_its_declared_range(path: str) -> None:
    pinned = pins(ROOT / path)
    for name, requirement in declared().items():
        assert name in pinned, f"{path} pins no version of {name}"
        assert requirement.specifier.contains(pinned[name], prereleases=True), (
            f"{path}: {name}=={pinned[name]} is outside {requirement.specifier}"
        )


def test_the_oldest_leg_pins_every_lower_bound() -> None:
    pinned = pins(ROOT / "ci" / "oldest.txt")
    for name, requirement in declared().items():
        (lower,) = [Version(spec.version) for spec in requirement.specifier if spec.operator == ">="]
        assert pinned[name] == lower, f"ci/oldest.txt: {name}=={pinned[name]}, the declared lower bound is {lower}"


def test_the_quick_start_installs_from_the_lock() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    commands = re.findall(r"```bash\n(.*?)```", section, flags=re.S)
    assert commands and all("-c requirements.lock" in command for command in commands)


def test_each_stack_leg_has_its_test_file() -> None:
    stacks = sorted(path.stem for path in (ROOT / "ci" / "stacks").glob("*.txt"))
    assert stacks, "no stack legs in ci/stacks"
    for stack in stacks:
        assert (ROOT / "tests" / "stacks" / f"test_{stack}.py").is_file(), f"ci/stacks/{stack}.txt has no test file"


def test_reproduce_names_the_locked_mujoco(monkeypatch: pytest.MonkeyPatch) -> None:
    import mujoco

    from energy_margin.cli.reproduce import LOCKED_MUJOCO, locked_engine_note

    assert Version(LOCKED_MUJOCO) == pins(ROOT / "requirements.lock")["mujoco"]
    monkeypatch.setattr(mujoco, "__version__", LOCKED_MUJOCO)
    assert locked_engine_note() is None
    monkeypatch.setattr(mujoco, "__version__", "3.3.0")
    note = locked_engine_note()
    assert note is not None and "made with MuJoCo 4.0.0 (requirements.lock); this is MuJoCo 3.3.0" in note
