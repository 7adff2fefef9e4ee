"""find_mujoco: the model and data behind each stack's environment, through its wrappers.

The shapes below are those of the stacks (robosuite's ``sim.model._model``, dm_control's
``physics.model.ptr``, gym-aloha's ``unwrapped._env.physics``); the stacks themselves are tested in
their own CI legs (tests/stacks).
"""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import pytest

from energy_margin.errors import EnergyMarginError
from energy_margin.integrations.handles import find_mujoco

MODEL = mujoco.MjModel.from_xml_string(
    "<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>"
)


@pytest.fixture
def data() -> mujoco.MjData:
    return mujoco.MjData(MODEL)


def gymnasium_like(data: mujoco.MjData) -> object:
    inner = SimpleNamespace(model=MODEL, data=data)
    return SimpleNamespace(unwrapped=inner, env=SimpleNamespace(env=inner))


def robosuite_like(data: mujoco.MjData) -> object:
    sim = SimpleNamespace(model=SimpleNamespace(_model=MODEL), data=SimpleNamespace(_data=data))
    return SimpleNamespace(env=SimpleNamespace(sim=sim))  # GymWrapper(env): .env is robosuite's own


def dm_control_like(data: mujoco.MjData) -> object:
    physics = SimpleNamespace(model=SimpleNamespace(ptr=MODEL), data=SimpleNamespace(ptr=data))
    return SimpleNamespace(unwrapped=SimpleNamespace(_env=SimpleNamespace(physics=physics)))


@pytest.mark.parametrize("build", [gymnasium_like, robosuite_like, dm_control_like])
def test_the_model_and_data_are_found_through_the_wrappers(build, data: mujoco.MjData) -> None:  # type: ignore[no-untyped-def]
    model, found = find_mujoco(build(data))
    assert model is MODEL and found is data


def test_a_pair_and_a_bare_physics_are_accepted(data: mujoco.MjData) -> None:
    assert find_mujoco((MODEL, data))[1] is data
    physics = SimpleNamespace(model=SimpleNamespace(ptr=MODEL), data=SimpleNamespace(ptr=data))
    assert find_mujoco(physics)[1] is data


def test_a_cycle_of_wrappers_ends_in_one_line() -> None:
    looped = SimpleNamespace()
    looped.env = looped
    with pytest.raises(EnergyMarginError, match=r"^SimpleNamespace has no MuJoCo model: looked for"):
        find_mujoco(looped)
    with pytest.raises(EnergyMarginError, match=r"^my-env \(object\) has no MuJoCo model"):
        find_mujoco(object(), what="my-env")
