"""The optional simulator capabilities of ``sim.base`` and the check that asks for one."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.sim.base import (
    BatchedRollout,
    CompiledModel,
    MissingCapabilityError,
    ModelCommand,
    ModelCommands,
    ReleasableStates,
    release_states,
    require,
)
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.sim.mujoco_spec import build_model, scene_index
from energy_margin.world.scene import Scene


class _Plain:
    """A simulator with none of the optional capabilities."""


def test_the_mujoco_simulator_has_every_capability(make_block_scene: Callable[..., Scene]) -> None:
    simulator = MujocoSimulator(make_block_scene(2))
    for capability in (BatchedRollout, ModelCommands, CompiledModel, ReleasableStates):
        assert require(simulator, capability, purpose="a test") is simulator
    propagator = require(simulator, BatchedRollout, purpose="a test").rollout_propagator(1)
    assert propagator is simulator.rollout_propagator(1)
    assert propagator.state_size > simulator.scene.n_objects


def test_a_missing_capability_is_named() -> None:
    with pytest.raises(MissingCapabilityError, match=r"^batched expansion needs a simulator with batched") as error:
        require(_Plain(), BatchedRollout, purpose="batched expansion")
    assert isinstance(error.value, EnergyMarginError)
    assert error.value.capability is BatchedRollout
    assert error.value.missing == ("rollout_propagator",)
    assert "_Plain has no rollout_propagator: use the 'mujoco' engine" in str(error.value)
    with pytest.raises(EnergyMarginError, match="has no model, data"):
        require(_Plain(), CompiledModel, purpose="record")


def test_only_capabilities_are_checked() -> None:
    with pytest.raises(TypeError, match="not a simulator capability"):
        require(_Plain(), int, purpose="a test")


def test_a_capability_one_instance_holds_is_not_granted_to_its_class() -> None:
    class _Commanded:
        def set_model_command(self, command: ModelCommand) -> None:
            del command

    class _Sometimes:
        """A class whose instances may be given the member one by one."""

    for _ in range(2):  # the second call takes the class's checked answer
        simulator = _Commanded()
        assert require(simulator, ModelCommands, purpose="a test") is simulator
    given = _Sometimes()
    given.set_model_command = lambda command: None  # type: ignore[attr-defined]
    assert require(given, ModelCommands, purpose="a test") is given
    with pytest.raises(MissingCapabilityError, match="_Sometimes has no set_model_command"):
        require(_Sometimes(), ModelCommands, purpose="a test")


def test_model_commands_go_through_the_capability(make_block_scene: Callable[..., Scene]) -> None:
    with pytest.raises(EnergyMarginError, match=r"^task 'x' needs a simulator with MuJoCo model commands"):
        ModelCommand(ctrl=np.zeros(0)).apply_to(_Plain(), purpose="task 'x'")
    simulator = MujocoSimulator(make_block_scene(1))
    ModelCommand(ctrl=np.zeros(0)).apply_to(simulator)


def test_release_states_only_where_provided() -> None:
    released = []

    class _Snapshots:
        def release_states(self) -> None:
            released.append(True)

    release_states(_Plain())
    release_states(_Snapshots())
    assert released == [True]


def test_a_given_model_comes_with_its_index(make_block_scene: Callable[..., Scene]) -> None:
    scene = make_block_scene(2, motion="upright")
    model = build_model(scene)
    simulator = MujocoSimulator(scene, model=model, index=scene_index(model, scene))
    assert simulator.model is model
    np.testing.assert_array_equal(simulator.index.object_bodies, [1, 2])
    with pytest.raises(InvalidParameterError, match=r"^index must be given together with model"):
        MujocoSimulator(scene, model=model)
