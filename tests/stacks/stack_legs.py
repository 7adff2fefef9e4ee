"""What the stack tests share: skip where the stack is not installed, fail where its leg asks for it.

A stack test (``tests/stacks/test_*.py``) runs a user's simulation stack (Meta-World,
gymnasium-robotics) on the MuJoCo version that stack needs; the main test leg lacks it, so the
test skips there with the reason. Its own leg (``pip install . -r ci/stacks/NAME.txt``) sets
``ENERGY_MARGIN_STACK_LEG=NAME``: there a missing stack is a failure, not a skip.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest

#: The environment variable a stack leg sets to its name (comma separated for several).
LEG_VARIABLE = "ENERGY_MARGIN_STACK_LEG"


def _required(leg: str) -> bool:
    return leg in os.environ.get(LEG_VARIABLE, "").split(",")


def skip_unless(condition: bool, *, leg: str, reason: str) -> None:
    """Skip the module unless ``condition`` holds (in the leg ``leg``: fail)."""
    if condition:
        return
    if _required(leg):
        pytest.fail(f"{LEG_VARIABLE}={leg}: {reason}", pytrace=False)
    pytest.skip(reason, allow_module_level=True)


def require(module: str, *, leg: str, reason: str) -> ModuleType:
    """``module`` imported, or the module skipped with ``reason`` (in the leg ``leg``: a failure)."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        skip_unless(False, leg=leg, reason=f"{reason} ({error})")
        raise  # pragma: no cover - skip_unless raised


def mujoco_version() -> tuple[int, ...]:
    """The installed MuJoCo's version as numbers (``3.11.0`` -> ``(3, 11, 0)``)."""
    import mujoco

    return tuple(int(part) for part in mujoco.__version__.split(".")[:3] if part.isdigit())
