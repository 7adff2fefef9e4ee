"""The task protocols: every built-in task implements all four; a consumer takes its narrowest one.

Also the ``RobotState`` hooks and the adapter of task classes still written with the old five
arguments ``(drive, time, robot_q, robot_v, rng)``.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import field_membership, score_field
from energy_margin.planning.tree import CostField
from energy_margin.tasks import (
    DesignSpace,
    PhysicsReadout,
    PushingTask,
    RobotState,
    ScoopingTask,
    ScriptedMotion,
    Task,
    TaskRegions,
    command_robot,
    get_task,
)
from energy_margin.tasks.protocols import __all__ as protocol_names
from energy_margin.tasks.region_types import Region
from energy_margin.tasks.regions import BoxRegion
from energy_margin.world.state import FrameState
from tiny_scene import write_tiny_scene

PROTOCOLS = (PhysicsReadout, ScriptedMotion, TaskRegions, DesignSpace)


def _tasks(tmp_path: Path) -> list[Task]:
    scene_file = write_tiny_scene(tmp_path / "scene")
    return [PushingTask(), ScoopingTask(), get_task("scene", {"scene_file": str(scene_file)})]


def test_every_protocol_is_exported() -> None:
    assert sorted(protocol_names) == sorted(protocol.__name__ for protocol in PROTOCOLS)


def test_every_built_in_task_satisfies_every_protocol(tmp_path: Path) -> None:
    for task in _tasks(tmp_path):
        for protocol in PROTOCOLS:
            assert isinstance(task, protocol), f"{task.name} is not a {protocol.__name__}"


def test_the_task_docstring_names_every_protocol() -> None:
    for protocol in PROTOCOLS:
        assert f"``{protocol.__name__}``" in (Task.__doc__ or "")


class _RegionsOnly:
    """Implements :class:`TaskRegions` and nothing else: everything inside x <= 0 is captured and successful."""

    region_caption = ""

    def _region(self) -> Region:
        return BoxRegion(np.array([-5.0, 0.0, 0.0]), np.array([5.0, 10.0, 10.0]))

    def capture_region(self, root: FrameState) -> Region:
        return self._region()

    def capture_regions(self, roots: Sequence[FrameState]) -> Region:
        return self._region()

    def capture_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        return np.all(self._region().contains(object_pos, object_vel), axis=-1)

    def success_region(self) -> Region:
        return self._region()

    def success_region_at(self, root: FrameState) -> Region:
        return self._region()

    def success_inside(
        self,
        root: FrameState,
        object_pos: np.ndarray,
        object_vel: np.ndarray,
        object_quat: np.ndarray | None = None,
        robot_q: np.ndarray | None = None,
    ) -> np.ndarray:
        return np.all(self._region().contains(object_pos, object_vel), axis=-1)

    def is_captured(self, frame: FrameState) -> bool:
        return bool(np.all(self._region().contains(frame.object_pos, frame.object_vel)))

    def is_successful(self, frame: FrameState) -> bool:
        return self.is_captured(frame)

    def capture_region_shape(self, root: FrameState) -> str:
        return "box"


def test_a_regions_only_object_is_accepted_where_regions_suffice() -> None:
    fake = _RegionsOnly()
    assert isinstance(fake, TaskRegions)
    assert not isinstance(fake, PhysicsReadout | ScriptedMotion | DesignSpace)
    positions = np.array([[[-1.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]]])
    field = CostField(
        costs=np.array([0.0, 1.0]),
        object_pos=positions,
        object_vel=np.zeros((2, 1, 6)),
        parents=np.array([-1, 0]),
        times=np.zeros(2),
        expansions=1,
        physics_s=0.0,
        total_s=0.0,
    )
    root = FrameState(positions[0], np.array([[1.0, 0.0, 0.0, 0.0]]), np.zeros((1, 6)), np.zeros(0), np.zeros(0))
    captured, successful = field_membership(fake, root, field)
    np.testing.assert_array_equal(captured, [True, False])
    np.testing.assert_array_equal(successful, [True, False])
    capture, success = score_field(fake, root, field, 0.0)
    assert capture == success == pytest.approx(0.5)


def test_a_regions_only_object_labels_a_recorded_trajectory() -> None:
    from energy_margin.data.generate import trajectory_record

    fake = _RegionsOnly()
    inside = FrameState(
        np.array([[-1.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0, 0.0]]), np.zeros((1, 6)), np.zeros(0), np.zeros(0)
    )
    outside = FrameState(
        np.array([[1.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0, 0.0]]), np.zeros((1, 6)), np.zeros(0), np.zeros(0)
    )
    record = trajectory_record(fake, [inside, outside], [0.0, 0.5], 0.3, np.zeros(1))
    np.testing.assert_array_equal(record["captured"], [True, False])
    np.testing.assert_array_equal(record["in_success"], [True, False])


class _DesignOnly:
    """A design space and nothing else: a configuration and no aliases."""

    config = PushingTask().config

    def design_aliases(self) -> tuple[()]:
        return ()


def test_a_design_only_object_gives_its_fields() -> None:
    from energy_margin.design.grid import config_fields

    fake = _DesignOnly()
    assert config_fields(fake) == config_fields(PushingTask())  # type: ignore[arg-type]
    assert config_fields(fake)["object_radius"] == PushingTask().config.object_radius  # type: ignore[arg-type]


def _legacy_class() -> type[PushingTask]:
    """A task class of another package, written against the old five-argument hooks (warned about once)."""
    with pytest.warns(DeprecationWarning, match=r"_LegacyPushing: robot_force and robot_targets take \(drive, time"):

        class _LegacyPushing(PushingTask):
            name = "legacy-pushing"

            def robot_force(  # type: ignore[override]
                self,
                drive: np.ndarray,
                time: float,
                robot_q: np.ndarray,
                robot_v: np.ndarray,
                rng: np.random.Generator | None,
            ) -> np.ndarray:
                return np.array([drive[0], time, robot_q[0], robot_v[0]])

            def robot_targets(  # type: ignore[override]
                self,
                drive: np.ndarray,
                time: float,
                robot_q: np.ndarray,
                robot_v: np.ndarray,
                rng: np.random.Generator | None,
            ) -> np.ndarray:
                return np.array([time, 0.0, 0.0, 0.0])

    return _LegacyPushing


def test_old_signature_hooks_are_adapted_with_a_deprecation_warning() -> None:
    base = _legacy_class()
    with pytest.warns(DeprecationWarning, match=r"Legacy: robot_force takes") as caught:

        class Legacy(base):  # type: ignore[valid-type,misc]
            def robot_force(  # type: ignore[override]
                self,
                drive: np.ndarray,
                time: float,
                robot_q: np.ndarray,
                robot_v: np.ndarray,
                rng: np.random.Generator | None,
            ) -> np.ndarray:
                return super().robot_force(drive, time, robot_q, robot_v, rng) * 2.0

    assert len(caught) == 1
    state = RobotState(np.array([3.0]), 0.5, np.array([1.0, 0, 0, 0]), np.array([2.0, 0, 0, 0]))
    task = Legacy()
    np.testing.assert_array_equal(task.robot_force(state, None), [6.0, 1.0, 2.0, 4.0])
    np.testing.assert_array_equal(task.robot_targets(state, None), [0.5, 0.0, 0.0, 0.0])
    # The old call still reaches the old hook.
    np.testing.assert_array_equal(task.robot_force(np.array([3.0]), 0.5, state.q, state.v, None), [6.0, 1.0, 2.0, 4.0])


def test_command_robot_hands_an_adapted_task_the_robot_state() -> None:
    class Recorder:
        def __init__(self) -> None:
            self.force: np.ndarray | None = None
            self.targets: np.ndarray | None = None

        def robot_positions(self) -> np.ndarray:
            return np.array([1.0, 0.0, 0.0, 0.0])

        def robot_velocities(self) -> np.ndarray:
            return np.array([2.0, 0.0, 0.0, 0.0])

        def set_robot_force(self, force: np.ndarray) -> None:
            self.force = force

        def set_robot_targets(self, targets: np.ndarray) -> None:
            self.targets = targets

    recorder = Recorder()
    command_robot(_legacy_class()(), recorder, np.array([3.0]), 0.25, None)  # type: ignore[arg-type]
    np.testing.assert_array_equal(recorder.force, [3.0, 0.25, 1.0, 2.0])
    np.testing.assert_array_equal(recorder.targets, [0.25, 0.0, 0.0, 0.0])


def test_new_signature_hooks_are_not_warned_about() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)

        class Current(PushingTask):
            name = "current-pushing"

            def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
                return super().robot_force(state, rng) + 1.0

    state = RobotState(np.array([0.0, 4.0]), 0.0, np.zeros(4), np.zeros(4))
    np.testing.assert_array_equal(Current().robot_force(state, None), [1.0, 5.0, 1.0, 1.0])
