"""The test legs, the same locally and in CI: ``nox -s newest``, ``nox -s oldest``, ``nox -s "stack(metaworld)"``.

* ``newest``: the locked versions (``requirements.lock``), what the README's quick start installs.
* ``oldest``: every lower bound ``pyproject.toml`` declares (``ci/oldest.txt``: MuJoCo 3.3.0, numpy 1.26, ...).
* ``gpu``: the ``mujoco-warp`` engine on the CPU device, with the locked ``gpu`` extra (its tests only).
* ``stack(NAME)``: the package installed beside one user stack through pip's resolver
  (``ci/stacks/NAME.txt``), on the MuJoCo that stack needs, running that stack's tests only
  (``tests/stacks/test_NAME.py``).

Arguments after ``--`` go to pytest (``nox -s oldest -- -x tests/sim``).
"""

from __future__ import annotations

import os
from pathlib import Path

import nox

nox.options.default_venv_backend = "venv"
nox.options.sessions = ["newest", "oldest"]

ROOT = Path(__file__).parent
LOCK = "requirements.lock"
OLDEST = "ci/oldest.txt"
STACKS = sorted(path.stem for path in (ROOT / "ci" / "stacks").glob("*.txt"))


@nox.session(python="3.11")
def newest(session: nox.Session) -> None:
    """The suite on the locked versions."""
    session.install("-c", LOCK, ".[test]")
    session.run("python", "-m", "pytest", *session.posargs)


@nox.session(python="3.11")
def oldest(session: nox.Session) -> None:
    """The suite on every declared lower bound."""
    session.install("-c", OLDEST, ".[test]")
    session.run("python", "-m", "pytest", *session.posargs)


@nox.session(python="3.11")
def gpu(session: nox.Session) -> None:
    """The ``mujoco-warp`` engine on the CPU device (the locked ``gpu`` extra) and its tests."""
    session.install("-c", LOCK, ".[gpu]", "pytest", "hypothesis")
    session.run(
        "python",
        "-m",
        "pytest",
        "-p",
        "no:cacheprovider",
        "tests/sim/test_mujoco_warp.py",
        "tests/sim/test_engines.py",
        "tests/analysis/test_frames_together.py",
        *session.posargs,
    )


@nox.session(python="3.11")
@nox.parametrize("stack", STACKS, ids=STACKS)
def stack(session: nox.Session, stack: str) -> None:
    """One user stack beside the package, resolved by pip, and that stack's tests."""
    session.install(".", "-r", f"ci/stacks/{stack}.txt")
    # In its own leg a missing stack fails the test instead of skipping it (tests/stacks/stack_legs.py).
    session.run(
        "python",
        "-m",
        "pytest",
        "-p",
        "no:cacheprovider",
        f"tests/stacks/test_{stack}.py",
        *session.posargs,
        # gym-aloha renders its observations: MuJoCo's EGL renderer works headless.
        env={"ENERGY_MARGIN_STACK_LEG": stack, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")},
    )
