"""Batched propagations of a MuJoCo simulator through ``mujoco.rollout``.

The propagator behind :class:`~energy_margin.sim.base.BatchedRollout` (``rollout_propagator``
of :class:`~energy_margin.sim.mujoco_backend.MujocoSimulator`): the EST's batched expansion and the
MPPI controller roll many command sequences out together, multithreaded and outside the GIL.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from energy_margin.errors import InvalidParameterError, check_int
from energy_margin.sim.base import ModelCommand
from energy_margin.sim.mujoco_index import ModelIndex, apply_model_command
from energy_margin.world.state import RobotState

__all__ = [
    "RolloutPropagator",
]

_FULL_PHYSICS = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CONTROL_SPEC = (
    mujoco.mjtState.mjSTATE_CTRL
    | mujoco.mjtState.mjSTATE_QFRC_APPLIED
    | mujoco.mjtState.mjSTATE_XFRC_APPLIED
    | mujoco.mjtState.mjSTATE_MOCAP_POS
    | mujoco.mjtState.mjSTATE_MOCAP_QUAT
)


class RolloutPropagator:
    """Batched propagations of one simulator's model through ``mujoco.rollout``.

    States are ``mjSTATE_FULLPHYSICS`` vectors (time, qpos, qvel, act, ...): ``mujoco.rollout``
    starts from and returns these. Every propagation starts with a zero warm start of the
    constraint solver (``mjSTATE_INTEGRATION`` states of the one-at-a-time path carry the previous
    step's), so its result depends on nothing but its own inputs: the same on 1 or 2 threads and
    in any batch. The object wrenches, the end-effector's generalized forces and servo targets go
    in as per-step controls (``mjSTATE_XFRC_APPLIED | QFRC_APPLIED | CTRL``); the scripted command
    is evaluated from the propagation's start state (robot joint positions and velocities) at the
    times the one-at-a-time path evaluates it.

    Args:
        model: the simulator's compiled model.
        data: the simulator's data: its current state starts :meth:`current_state`, its held
            controls the sequences of :meth:`roll_commands` without targets.
        index: the objects' and the robot's addresses in ``model``.
        threads: worker threads (1 runs on the calling thread).

    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, index: ModelIndex, threads: int) -> None:
        from mujoco import rollout

        self.threads = check_int("threads", threads, minimum=1)
        self.model, self.data, self.index = model, data, index
        self._rollout = rollout.Rollout(nthread=threads if threads > 1 else 0)
        self._datas = [mujoco.MjData(model) for _ in range(threads)]
        self._scratch = mujoco.MjData(model)
        self.state_size = int(mujoco.mj_stateSize(model, _FULL_PHYSICS))
        self.control_size = int(mujoco.mj_stateSize(model, _CONTROL_SPEC))
        self._nq, self._nv = int(model.nq), int(model.nv)
        self._warmstart = np.zeros((0, self._nv))
        # The mocap poses in a control vector: after the controls, applied forces and wrenches.
        self._mocap_at = int(
            mujoco.mj_stateSize(
                model,
                mujoco.mjtState.mjSTATE_CTRL
                | mujoco.mjtState.mjSTATE_QFRC_APPLIED
                | mujoco.mjtState.mjSTATE_XFRC_APPLIED,
            )
        )
        self._end_mocap = np.zeros((0, 7 * int(model.nmocap)))

    def close(self) -> None:
        """Stop the thread pool."""
        self._rollout.close()

    def current_state(self, data: mujoco.MjData | None = None) -> np.ndarray:
        """The simulator's current state, or that of ``data`` (a model like this one), as a FULLPHYSICS vector."""
        state = np.empty(self.state_size)
        mujoco.mj_getState(self.model, self.data if data is None else data, state, _FULL_PHYSICS)
        return state

    def qpos_qvel(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and velocities of states (..., state_size)."""
        nq, nv = self._nq, self._nv
        return states[..., 1 : 1 + nq], states[..., 1 + nq : 1 + nq + nv]

    def _control(
        self, wrenches: np.ndarray, force: np.ndarray, targets: np.ndarray | None, command: ModelCommand | None
    ) -> np.ndarray:
        index, scratch = self.index, self._scratch
        scratch.xfrc_applied[index.object_bodies] = wrenches
        scratch.qfrc_applied[index.robot_qvel] = np.asarray(force)[: index.robot_qvel.size]
        if targets is not None and index.servo_actuators.size:
            scratch.ctrl[index.servo_actuators] = np.asarray(targets, dtype=float)[index.servoed]
        if command is not None:
            apply_model_command(scratch, command)
        row = np.empty(self.control_size)
        mujoco.mj_getState(self.model, scratch, row, _CONTROL_SPEC)
        return row

    def roll_commands(
        self,
        state: np.ndarray,
        forces: np.ndarray,
        targets: np.ndarray | None = None,
        ctrl: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Roll ``k`` end-effector command sequences out from one state, without object wrenches.

        Args:
            state: start state, a ``mjSTATE_FULLPHYSICS`` vector (:meth:`current_state`).
            forces: end-effector generalized forces of every step, shape (k, steps, n_robot_dofs),
                N or N m.
            targets: servo targets of every step, shape (k, steps, n_robot_dofs), m or rad;
                ``None`` keeps the targets held in ``state``'s model (none for a task without servos).
            ctrl: every actuator's control of every step, shape (k, steps, nu) (a user's model);
                ``None`` leaves the controls to ``targets``.

        Returns:
            The states after every step, shape (k, steps, state_size), and the end states
            (k, state_size).

        """
        index, model = self.index, self.model
        forces = np.asarray(forces, dtype=float)
        k, steps = forces.shape[:2]
        base = self._control(np.zeros((index.object_bodies.size, 6)), np.zeros(index.robot_qvel.size), None, None)
        if targets is None and index.servo_actuators.size:
            base[: model.nu] = self.data.ctrl
        controls = np.broadcast_to(base, (k, steps, self.control_size)).copy()
        # mjSTATE_CTRL comes first in the control vector, then mjSTATE_QFRC_APPLIED (nu + nv).
        controls[..., model.nu + index.robot_qvel] = forces
        if targets is not None and index.servo_actuators.size:
            controls[..., index.servo_actuators] = np.asarray(targets, dtype=float)[..., index.servoed]
        if ctrl is not None:
            controls[..., : model.nu] = ctrl
        initial = np.broadcast_to(state, (k, self.state_size)).copy()
        out = self._roll_all(initial, controls)
        return out, out[:, -1]

    def _roll_all(self, initial: np.ndarray, controls: np.ndarray) -> np.ndarray:
        """The states after every step, shape (k, steps, state_size), each from a zero warm start.

        Args:
            initial: start states, shape (k, state_size).
            controls: control vectors of every step, shape (k, steps, control_size).

        """
        k, steps = controls.shape[:2]
        out, _ = self._rollout.rollout(
            self.model,
            self._datas,
            initial,
            controls,
            control_spec=int(_CONTROL_SPEC),
            nstep=steps,
            initial_warmstart=np.zeros((k, self._nv)),
        )
        return out

    def _roll_to(
        self,
        initial: np.ndarray,
        chunks: np.ndarray,
        period: int,
        n_steps: np.ndarray,
        models: list[mujoco.MjModel] | None = None,
    ) -> np.ndarray:
        """The state of each propagation after its own ``n_steps`` (k,) steps, shape (k, state_size).

        Args:
            initial: start states, shape (k, state_size).
            chunks: the control vector of every command period, shape (k, n_chunks, control_size):
                step ``t`` holds ``chunks[:, t // period]``; a propagation past its own steps
                holds its last.
            period: steps per chunk.
            n_steps: steps of each propagation, shape (k,).
            models: each propagation's model (this propagator's when ``None``).

        """
        k = initial.shape[0]
        longest = int(n_steps.max())
        controls = np.repeat(chunks, period, axis=1)[:, :longest]
        if self._warmstart.shape[0] != k:
            self._warmstart = np.zeros((k, self._nv))
        out, _ = self._rollout.rollout(
            self.model if models is None else models,
            self._datas,
            initial,
            controls,
            control_spec=int(_CONTROL_SPEC),
            nstep=longest,
            initial_warmstart=self._warmstart,
        )
        return out[np.arange(k), n_steps - 1]

    def object_states(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Object positions, quaternions, velocities and robot coordinates of states (k, state_size).

        Returns:
            Positions (k, n_objects, 3), quaternions (k, n_objects, 4), velocities (k, n_objects, 6),
            robot joint positions (k, n_robot_dofs) and velocities (k, n_robot_dofs).

        """
        index = self.index
        qpos, qvel = self.qpos_qvel(states)
        pos, quat, vel = index.objects_of(qpos, qvel)
        return pos, quat, vel, qpos[:, index.robot_qpos], qvel[:, index.robot_qvel]

    def end_robot_positions(self, states: np.ndarray) -> np.ndarray:
        """The robot's coordinates at the end states (k, state_size) of the last :meth:`propagate`.

        Robot joint positions, then every mocap body's position (3) and quaternion (4) as the last
        control of each propagation set them (``mjSTATE_FULLPHYSICS`` holds no mocap pose), the
        layout of :meth:`~energy_margin.sim.mujoco_model.MujocoModelSimulator.robot_positions`
        (a model without mocap bodies: the joints only).
        """
        joints = self.object_states(states)[3]
        if self._end_mocap.shape != (states.shape[0], 7 * int(self.model.nmocap)):
            raise InvalidParameterError("states", f"are not the end states of the last propagation ({states.shape[0]})")
        return np.concatenate([joints, self._end_mocap], axis=1)

    def _controls_at_once(
        self,
        chunks: np.ndarray,
        period: int,
        task: Any,
        drives: np.ndarray,
        qpos: np.ndarray,
        qvel: np.ndarray,
        start_times: np.ndarray,
        wrenches: np.ndarray,
        n_steps: np.ndarray,
    ) -> bool:
        """Fill ``chunks`` (k, n_chunks, control_size) from the task's vectorised script, if it has one.

        A task may vectorise its nominal script: ``task.robot_commands(drives (k, n_drive), times
        (k,) s, q (k, r), v (k, r))`` returns the forces (k, r) and servo targets (k, r) or ``None``
        that ``Task.robot_force`` and ``Task.robot_targets`` give each state with ``rng=None``, bit
        for bit, or ``None`` to be evaluated one state at a time; a task with model commands has
        none. The built-in tasks have one. A task that moves its robot by model commands alone (no
        forces, no servo targets: a scene file's) may vectorise those instead:
        ``task.batched_model_command(drives (k, n_drive), times (k,) s)`` returns the
        :class:`~energy_margin.sim.base.ModelCommand` of every row (arrays with a leading k axis)
        that ``Task.model_command`` gives row by row, or ``None``; its forces then come from
        ``task.batched_robot_force(drives, times)`` (k, r) where it has one (zero otherwise).

        The same numbers as the loop of :meth:`propagate`, to the last bit: commands at the same
        times (start + done * dt, done a multiple of ``period``), packed into the same vector (the
        scratch data's, with each row's wrenches, forces and targets in their slots).

        Returns:
            Whether it did (``False``: the task evaluates one state at a time).

        """
        robot_commands = getattr(task, "robot_commands", None)
        model_commands = getattr(task, "batched_model_command", None)
        model_forces = getattr(task, "batched_robot_force", None)
        if robot_commands is None and model_commands is None:
            return False
        index, model = self.index, self.model
        k = chunks.shape[0]
        dt = float(model.opt.timestep)
        robot_q, robot_v = qpos[:, index.robot_qpos], qvel[:, index.robot_qvel]
        base = np.empty(self.control_size)
        mujoco.mj_getState(model, self._scratch, base, _CONTROL_SPEC)
        nu, nv = int(model.nu), int(model.nv)
        force_at = nu + index.robot_qvel
        wrench_at = (nu + nv + 6 * index.object_bodies[:, None] + np.arange(6)).ravel()
        rows = np.broadcast_to(base, (k, self.control_size)).copy()
        rows[:, wrench_at] = wrenches.reshape(k, -1)
        for c in range(chunks.shape[1]):
            done = c * period
            active = np.flatnonzero(n_steps > done)
            times = start_times[active] + done * dt
            if robot_commands is None:
                assert model_commands is not None  # one of the two, checked above
                command = model_commands(drives[active], times)
                if command is None:
                    return False
                if model_forces is None:
                    rows[np.ix_(active, force_at)] = 0.0
                else:
                    rows[np.ix_(active, force_at)] = model_forces(drives[active], times)[:, : index.robot_qvel.size]
                self._write_model_commands(rows, active, command)
                chunks[:, c] = rows
                continue
            commands = robot_commands(drives[active], times, robot_q[active], robot_v[active])
            if commands is None:
                return False
            forces, targets = commands
            rows[np.ix_(active, force_at)] = np.asarray(forces)[:, : index.robot_qvel.size]
            if targets is not None and index.servo_actuators.size:
                rows[np.ix_(active, index.servo_actuators)] = np.asarray(targets, dtype=float)[:, index.servoed]
            chunks[:, c] = rows  # a propagation past its last command holds it
        return True

    def _write_model_commands(self, rows: np.ndarray, active: np.ndarray, command: ModelCommand) -> None:
        """Write each active row's controls and mocap poses (``command``'s arrays, one row each) into ``rows``."""
        nmocap = int(self.model.nmocap)
        at = self._mocap_at
        if command.ctrl is not None:
            rows[active, : int(self.model.nu)] = command.ctrl
        if command.mocap_pos is not None:
            rows[active, at : at + 3 * nmocap] = np.reshape(command.mocap_pos, (active.size, 3 * nmocap))
        if command.mocap_quat is not None:
            rows[active, at + 3 * nmocap : at + 7 * nmocap] = np.reshape(command.mocap_quat, (active.size, 4 * nmocap))

    def propagate(
        self,
        task: Any,
        drive: np.ndarray,
        states: np.ndarray,
        start_times: np.ndarray,
        wrenches: np.ndarray,
        n_steps: np.ndarray,
        control_steps: int | None,
        models: list[mujoco.MjModel] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Propagate every state with its wrenches for its number of steps.

        Args:
            task: the task (its scripted ``robot_force`` and ``robot_targets``, without variation).
            drive: the trajectory's drive parameters, shape (n_drive,), or each propagation's,
                shape (k, n_drive).
            states: start states, shape (k, state_size).
            start_times: script time at each start, shape (k,), s.
            wrenches: object wrenches, shape (k, n_objects, 6).
            n_steps: steps of each propagation, shape (k,), >= 1; shorter ones are padded to the
                longest and read at their own last step.
            control_steps: the command is re-evaluated every this many steps (``None``: once).
            models: each propagation's model, shape (k,) (``None``: this propagator's): models of
                other roll-outs of the same scene, which differ from it in numbers only
                (friction, masses), not in structure.

        Returns:
            Object positions (k, n_objects, 3), velocities (k, n_objects, 6), quaternions
            (k, n_objects, 4) and end states (k, state_size).

        """
        index = self.index
        k = states.shape[0]
        longest = int(n_steps.max())
        dt = float(self.model.opt.timestep)
        qpos, qvel = self.qpos_qvel(states)
        drives = np.broadcast_to(drive, (k, np.shape(drive)[-1]))
        # One control vector per command period: step t of a propagation holds chunks[:, t // period].
        period = longest if control_steps is None else int(control_steps)
        chunks = np.empty((k, -(-longest // period), self.control_size))
        # A command without mocap poses holds those of the simulator's state (the tree's root), as
        # the one-at-a-time path restores them with each node's state.
        self._scratch.mocap_pos[:] = self.data.mocap_pos
        self._scratch.mocap_quat[:] = self.data.mocap_quat
        if not self._controls_at_once(chunks, period, task, drives, qpos, qvel, start_times, wrenches, n_steps):
            for j in range(k):
                robot_q, robot_v = qpos[j, index.robot_qpos], qvel[j, index.robot_qvel]
                steps = int(n_steps[j])
                for c in range(chunks.shape[1]):
                    done = c * period
                    if done < steps:
                        time = float(start_times[j]) + done * dt
                        state = RobotState(drives[j], time, robot_q, robot_v)
                        force = task.robot_force(state, None)
                        targets = task.robot_targets(state, None)
                        row = self._control(wrenches[j], force, targets, task.model_command(drives[j], time))
                    chunks[j, c] = row  # past its last command, a propagation holds it
        final = self._roll_to(states, chunks, period, n_steps, models)
        nmocap = int(self.model.nmocap)
        last = chunks[np.arange(k), (n_steps - 1) // period]
        self._end_mocap = last[:, self._mocap_at : self._mocap_at + 7 * nmocap]
        pos, quat, vel = index.objects_of(*self.qpos_qvel(final))
        return pos, vel, quat, final
