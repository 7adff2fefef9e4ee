"""Every check of a keyword argument raises InvalidParameterError naming it; data errors are InvalidDataError."""

from __future__ import annotations

import ast
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.errors import EnergyMarginError, InvalidDataError, InvalidParameterError
from energy_margin.tasks.pushing import PushingConfig
from energy_margin.tasks.scooping import ScoopingConfig
from energy_margin.tasks.state_box import StateBox
from energy_margin.world.ellipsoid import min_volume_ellipsoid

SOURCE = Path(__file__).resolve().parents[1] / "src" / "energy_margin"


@pytest.mark.parametrize(
    ("make", "parameter", "message"),
    [
        (lambda: AnalyzerConfig(expansions=None, nodes=None), "expansions", "and nodes cannot both be None"),
        (lambda: AnalyzerConfig(batch=2, cost="energy"), "cost", "does not integrate friction work"),
        (lambda: AnalyzerConfig(contacts="fast", engine="pybullet"), "contacts", "'fast' is a MuJoCo contact model"),
        (lambda: AnalyzerConfig(expansions=-1), "expansions", "must be a non-negative integer, got -1"),
        (lambda: PushingConfig(tine_count=1), "tine_count", "must be an integer >= 2, got 1"),
        (lambda: PushingConfig(timestep=2.0, duration=1.0), "timestep", "must not exceed duration"),
        (lambda: ScoopingConfig(recorded_waypoints=1), "recorded_waypoints", "must be 0 or at least 2, got 1"),
        (lambda: StateBox(low=(0.0, 0.0, 1.0), high=(1.0, 1.0, 1.0), max_speed=1.0), "low", "must be below high"),
        (lambda: StateBox(low=(0.0,) * 3, high=(1.0,) * 3, max_speed=0.0), "max_speed", "must be a finite number > 0"),
        (lambda: min_volume_ellipsoid(np.array([[np.nan, 0.0]])), "points", "must be finite"),
    ],
)
def test_a_bad_keyword_argument_is_named(make: Callable[[], object], parameter: str, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message) as caught:
        make()
    assert caught.value.parameter == parameter
    assert str(caught.value).startswith(f"{parameter} ")
    assert isinstance(caught.value, EnergyMarginError) and isinstance(caught.value, ValueError)


def test_a_data_error_is_a_user_error_and_a_value_error() -> None:
    error = InvalidDataError("scene file s.toml changed since these data were made")
    assert isinstance(error, EnergyMarginError) and isinstance(error, ValueError)


def test_a_plain_value_error_is_left_only_for_a_defect_and_says_why() -> None:
    # A plain ValueError signals a defect no user input reaches; the line above it says why.
    plain = []
    for path in sorted(SOURCE.rglob("*.py")):
        lines = path.read_text().splitlines()
        for node in ast.walk(ast.parse("\n".join(lines))):
            if isinstance(node, ast.Raise) and node.exc is not None:
                call = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
                if isinstance(call, ast.Name) and call.id == "ValueError":
                    above = lines[node.lineno - 2].strip()
                    plain.append((path.relative_to(SOURCE).as_posix(), node.lineno, above.startswith("#")))
    assert all(commented for _, _, commented in plain), plain
    assert len(plain) <= 3, plain
