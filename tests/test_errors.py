import math

import numpy as np
import pytest

from energy_margin.errors import (
    EnergyMarginError,
    InvalidParameterError,
    check_choice,
    check_float,
    check_int,
    check_positive_float,
    check_positive_int,
    check_seed,
)


def test_invalid_parameter_is_both_a_user_error_and_a_value_error() -> None:
    error = InvalidParameterError("workers", "must be a positive integer, got 0")
    assert isinstance(error, EnergyMarginError) and isinstance(error, ValueError)
    assert str(error) == "workers must be a positive integer, got 0"
    assert error.parameter == "workers" and error.reason == "must be a positive integer, got 0"


@pytest.mark.parametrize("value", [True, 1.0, "3", None, np.float64(2.0)])
def test_check_int_refuses_what_is_not_an_integer(value: object) -> None:
    with pytest.raises(InvalidParameterError, match=r"^n must be an integer") as caught:
        check_int("n", value)
    assert caught.value.parameter == "n"


def test_check_int_bounds_and_numpy_integers() -> None:
    assert check_int("n", np.int64(3), minimum=1) == 3 and type(check_int("n", np.int64(3))) is int
    assert check_int("n", 5, minimum=0, maximum=5) == 5
    with pytest.raises(InvalidParameterError, match=r"^n must be an integer in \[0, 5\], got 6$"):
        check_int("n", 6, minimum=0, maximum=5)
    with pytest.raises(InvalidParameterError, match=r"^n must be a positive integer, got 0$"):
        check_positive_int("n", 0)
    with pytest.raises(InvalidParameterError, match=r"^n must be an integer >= 2, got 1$"):
        check_int("n", 1, minimum=2)
    with pytest.raises(InvalidParameterError, match=r"^seed must be a non-negative integer, got -1$"):
        check_seed(-1)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, "x", "1.5", None, True, 10**400])
def test_check_float_refuses_non_finite_and_non_numbers(value: object) -> None:
    with pytest.raises(InvalidParameterError, match=r"^x must be a finite number"):
        check_float("x", value)


def test_check_float_bounds() -> None:
    assert check_float("x", 0, minimum=0.0) == 0.0
    with pytest.raises(InvalidParameterError, match=r"^x must be a finite number > 0, got 0$"):
        check_positive_float("x", 0)
    assert check_positive_float("x", 0, allow_zero=True) == 0.0
    with pytest.raises(InvalidParameterError, match=r"^x must be a finite number >= 0 and < 1, got 1.0$"):
        check_float("x", 1.0, minimum=0.0, maximum=1.0, exclusive_maximum=True)


def test_check_choice_names_the_choices() -> None:
    assert check_choice("engine", "mujoco", ("mujoco", "pybullet")) == "mujoco"
    with pytest.raises(InvalidParameterError, match=r"^engine must be one of mujoco, pybullet, got 'ode'$"):
        check_choice("engine", "ode", ("mujoco", "pybullet"))


def test_a_declared_constraint_checks_with_the_validators() -> None:
    from energy_margin.errors import Constraint

    assert Constraint("int", minimum=0, optional=True).check("nodes", None) is None
    with pytest.raises(InvalidParameterError, match=r"^n must be a positive integer, got 0$"):
        Constraint("int", minimum=1).check("n", 0)
    with pytest.raises(InvalidParameterError, match=r"^x must be a finite number > 0 and < 1, got 1.0$"):
        Constraint("float", minimum=0.0, maximum=1.0, exclusive=True).check("x", 1.0)
    with pytest.raises(InvalidParameterError, match=r"^engine must be one of mujoco, got 'ode'$"):
        Constraint("choice", choices=("mujoco",)).check("engine", "ode")
