"""Energy margins of a running MuJoCo simulation: the state in a user's own ``MjModel`` / ``MjData``.

:class:`LiveModelScorer` is the mechanism under the Gymnasium wrapper
(:mod:`energy_margin.integrations.gymnasium`) and the dm_control one
(:mod:`energy_margin.integrations.dm_control`): it resolves the objects and the capture and success
regions against the user's compiled model (the tables a scene file holds, given in memory or as a
scene file), keeps its own copy of the model and its own ``MjData``, and scores the state held in
the user's ``MjData`` by growing the tree within a wall-clock budget
(:func:`~energy_margin.analysis.live.score_state`) or with a learned margin
(:class:`~energy_margin.learning.margin_model.MarginModel`). The user's model and data are only
read: scoring never writes to them, so the simulation goes on exactly as without it.

During the tree's propagation the robot holds its last command (zero-order hold): the actuator
controls and mocap poses found in the user's ``MjData`` stay as they are, and the robot starts
with its current velocity (``hold="action"``, the default). With ``hold="still"`` the robot is
held where it is instead (a scene's ``motion.robot = "still"``: its joint velocities start at zero
and its joints get an armature of :data:`~energy_margin.sim.mujoco_model.STILL_ARMATURE` kg m^2 or
kg, so that no actuator, gravity or contact force moves it measurably during the propagation);
with ``hold="coasting"`` it keeps its current joint velocities under an armature of
:data:`~energy_margin.sim.mujoco_model.COASTING_ARMATURE` (a scene's ``motion.robot =
"coasting"``); mocap bodies stay where they are in every case. A scene whose
robot follows its recorded path (``motion.robot = "recorded"``, for roll-outs analysed afterwards)
holds its last command live, or does what ``hold`` says.

What a wrapper does around an episode (scoring every few steps, recording the rows) is
:mod:`energy_margin.integrations.live_session`.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import mujoco
import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.live import MAX_EXPANSIONS, FeedbackContinuation, LiveScore, score_state
from energy_margin.errors import EnergyMarginError, check_choice, check_positive_float, check_positive_int
from energy_margin.integrations.live_policy import Policy, PolicyControllers
from energy_margin.sim.base import CompiledModel, ModelCommand, require
from energy_margin.sim.mujoco_audit import WarningLog
from energy_margin.tasks.scene_file import read_scene_file, scene_spec_from_tables, set_table
from energy_margin.tasks.scene_model import LoadedScene, resolve_scene
from energy_margin.tasks.scene_task import SceneTask
from energy_margin.world.state import FrameState

__all__ = [
    "INFO_KEYS",
    "OVERRUN_WINDOW",
    "HeldCommandTask",
    "Hold",
    "LiveModelScorer",
    "LiveOptions",
    "scene_tables",
]

Hold = Literal["action", "still", "coasting"]

#: Calls whose overrun of the tree's budget sets the reserve of the next call's tree.
OVERRUN_WINDOW = 20

#: Keys of the ``info["energy_margin"]`` dictionary (and of :meth:`LiveModelScorer.score`).
INFO_KEYS = (
    "capture_score",
    "success_score",
    "expansions",
    "nodes",
    "ms",
    "stopped_by",
    "seed",
    "rejected",
    "diverged",
    "tree_capture_score",
    "continuation_ms",
)


class HeldCommandTask(SceneTask):
    """A scene task whose robot holds one command (the last one applied) while the tree grows."""

    held: ModelCommand = ModelCommand(ctrl=None, mocap_pos=None, mocap_quat=None)

    def __init__(self, *, loaded: LoadedScene) -> None:
        super().__init__(loaded=loaded)
        # The held command depends on neither time nor state: set once per propagation, it steps
        # exactly as when set every control period, in one ``mj_step`` call instead of one per period.
        self.control_period = None

    def model_command(self, drive: np.ndarray, time: float) -> ModelCommand | None:
        """The held command, whatever the time."""
        del drive, time
        return self.held


def scene_tables(
    *,
    objects: str | list[str] | tuple[str, ...] | None,
    capture: Mapping[str, Any] | None,
    success: Mapping[str, Any] | None,
    perturbation: Mapping[str, Any] | None = None,
    bounds: Mapping[str, Any] | None = None,
    joints: str | None = None,
) -> dict[str, Any]:
    """The tables of a scene file from a wrapper's keyword arguments (see :class:`LiveModelScorer`)."""
    if objects is None:
        raise EnergyMarginError("objects is missing: give the object bodies by name or glob, e.g. objects='object*'")
    if capture is None or success is None:
        missing = "capture" if capture is None else "success"
        raise EnergyMarginError(f"{missing} is missing: give its region table (as in a scene file) or scene=FILE")
    patterns = [objects] if isinstance(objects, str) else list(objects)
    document: dict[str, Any] = {
        "objects": {"bodies": patterns, **({"joints": joints} if joints is not None else {})},
        # A live state has no declared motion: the robot holds its last command.
        "motion": {"duration": 1.0},
        "capture": set_table("capture", capture),
        "success": set_table("success", success),
    }
    if perturbation is not None:
        document["perturbation"] = dict(perturbation)
    if bounds is not None:
        document["bounds"] = dict(bounds)
    return document


@dataclass(frozen=True)
class LiveOptions:
    """How a live scorer scores.

    Attributes:
        budget_s: wall-clock budget of one whole call, s (reading the state and scoring
            included; ``None``: stop at ``max_expansions`` only, deterministic). The tree gets the
            budget less the overrun measured on the scorer's earlier calls (see
            :meth:`LiveModelScorer.tree_budget`).
        max_expansions: most expansions of one tree.
        hold: ``"action"`` (the robot holds its last command), ``"still"`` (held where it is) or
            ``"coasting"`` (it keeps its current joint velocities).
        seed: root seed; call k uses the k-th child of ``numpy.random.SeedSequence(seed)``.
        config: further analysis settings (cost model, lambda, ...); its budgets are replaced.
        continuation: with a policy, the draws whose continuation under it scores success, >= 1.
        horizon_s: with a policy, how far its continuations run, s, where a call gives no horizon.

    """

    budget_s: float | None = 0.05
    max_expansions: int = MAX_EXPANSIONS
    hold: Hold = "action"
    seed: int = 0
    config: AnalyzerConfig | None = None
    continuation: int = 4
    horizon_s: float = 1.0


class LiveModelScorer:
    """Energy margins of states of a user's compiled MuJoCo model.

    Args:
        model: the user's compiled model (copied: later changes to it are not seen).
        objects: object body names or glob patterns (``"object*"``).
        capture: the capture set: a region table as in a scene file (``{"type": "distance",
            "body": "tips_arm", "max": 0.1}``) or ``{"region": ..., "at_least": n}``.
        success: the success set, likewise.
        scene: a scene file whose objects, perturbation, bounds and sets are used instead of the
            arguments above (its ``mjcf`` is not loaded: ``model`` is the model; its ``[randomize]``
            table is ignored: the model's own friction and masses are scored).
        perturbation: the scene file's ``[perturbation]`` table (wrench bounds, lambda).
        bounds: the scene file's ``[bounds]`` table.
        joints: ``"free"`` or ``"upright"`` objects; ``None`` detects it from the model.
        margin_model: a learned margin (a file of ``energy-margin learn`` or a loaded
            :class:`~energy_margin.learning.margin_model.MarginModel`) to use instead of the tree.
        options: budget, hold, seed and analysis settings.
        origin: what messages call the model, e.g. ``"Pusher-v5"``.
        policy: the policy driving the robot, ``policy(data) -> ctrl``
            (:mod:`~energy_margin.integrations.live_policy`): the success score is then continued
            under it from the tree's likely states to the call's horizon (after the tree, beyond
            ``budget_s``); ``None``: the tree's own success score.
        policy_period_s: time between two of the policy's commands, s (the environment's control
            step; ``None``: the model's time step).

    Raises:
        EnergyMarginError: objects that match no body, a region naming an unknown body or site,
            a scene file that cannot be read, a margin model of another task (one line each).

    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        objects: str | list[str] | tuple[str, ...] | None = None,
        capture: Mapping[str, Any] | None = None,
        success: Mapping[str, Any] | None = None,
        scene: str | Path | None = None,
        perturbation: Mapping[str, Any] | None = None,
        bounds: Mapping[str, Any] | None = None,
        joints: str | None = None,
        margin_model: Any = None,
        options: LiveOptions | None = None,
        origin: str = "model",
        policy: Policy | None = None,
        policy_period_s: float | None = None,
    ) -> None:
        options = options if options is not None else LiveOptions()
        if options.budget_s is not None:
            check_positive_float("budget_s", options.budget_s)
        check_positive_int("max_expansions", options.max_expansions)
        check_positive_int("continuation", options.continuation)
        check_positive_float("horizon_s", options.horizon_s)
        if policy_period_s is not None:
            check_positive_float("policy_period_s", policy_period_s)
        check_choice("hold", options.hold, ("action", "still", "coasting"))
        self.options = options
        model = copy.copy(model)
        if scene is not None:
            given = [
                name for name, value in (("objects", objects), ("capture", capture), ("success", success)) if value
            ]
            if given:
                raise EnergyMarginError(f"give either scene or {', '.join(given)}, not both")
            # The environment's physics as it is: a scene file's randomisation is for `generate`.
            spec = replace(read_scene_file(scene), friction_range=None, mass_scale=None, time_scale=None)
        else:
            tables = scene_tables(
                objects=objects, capture=capture, success=success, perturbation=perturbation, bounds=bounds
            )
            if joints is not None:
                tables["objects"]["joints"] = joints
            spec = scene_spec_from_tables(tables, origin=origin)
        if options.hold != "action":
            spec = replace(spec, motion=replace(spec.motion, robot=options.hold))
        elif spec.motion.robot == "recorded":
            # A live state has no recording to follow: the robot holds its last command.
            spec = replace(spec, motion=replace(spec.motion, robot="declared"))
        loaded = resolve_scene(spec, model)
        self.task = HeldCommandTask(loaded=loaded)
        self.friction = self.task.default_friction()
        self.drive = np.ones(self.task.drive_size())
        self.simulator = self.task.make_simulator(loaded.n_objects, self.friction, self.drive)
        compiled = require(self.simulator, CompiledModel, purpose="live scoring of a user's model")
        self._model, self._data = compiled.model, compiled.data
        if policy is not None and margin_model is not None:
            raise EnergyMarginError("give either a policy or a margin model, not both: a learned margin grows no tree")
        if policy is not None and options.hold != "action":
            raise EnergyMarginError(
                f"a policy drives the robot through its own actuators: give hold='action', not {options.hold!r}"
            )
        self.policy = PolicyControllers.of(policy, self._model) if policy is not None else None
        self.policy_period_s = policy_period_s if policy_period_s is not None else float(self._model.opt.timestep)
        self._seeds = np.random.SeedSequence(options.seed)
        self.margin_model = _load_model(margin_model, loaded.model_sha256)
        self._overruns: list[float] = []
        #: MuJoCo's warnings raised while growing trees (its log file is not written in the working directory).
        self.warning_log = WarningLog()

    @property
    def object_names(self) -> tuple[str, ...]:
        """The object bodies, in the order of the scores' states."""
        return self.task.loaded.object_names

    def frame(self, data: mujoco.MjData) -> FrameState:
        """The state held in the user's ``data`` (only read) as a frame of this scene."""
        own = self._data
        own.qpos[:] = data.qpos
        own.qvel[:] = data.qvel
        own.mocap_pos[:] = data.mocap_pos
        own.mocap_quat[:] = data.mocap_quat
        mujoco.mj_forward(self._model, own)
        state = self.simulator.frame_state()
        bad = ~np.isfinite(np.concatenate([state.object_pos.ravel(), state.object_vel.ravel(), state.robot_q]))
        if np.any(bad):
            raise EnergyMarginError("the simulation's state holds NaN or infinite values: it cannot be scored")
        return state

    def tree_budget(self) -> float | None:
        """The tree's wall-clock budget for the next call, s (``None`` without a budget).

        A call overruns the budget its tree is given by the last expansion, the final scoring and
        reading the state (about a millisecond on Pusher-v5). The tree therefore gets
        ``budget_s`` less the largest overrun of the last :data:`OVERRUN_WINDOW` calls, and never
        less than half of ``budget_s``; the first call gets all of it.
        """
        budget = self.options.budget_s
        if budget is None:
            return None
        reserve = max(self._overruns[-OVERRUN_WINDOW:], default=0.0)
        return max(budget - reserve, 0.5 * budget)

    def score(self, data: mujoco.MjData, *, horizon_s: float | None = None) -> dict[str, Any]:
        """Score the state held in ``data``: ``capture_score``, ``success_score``, ``expansions``, ``ms`` ...

        ``ms`` is the wall time of the whole call (reading the state included), milliseconds;
        ``continuation_ms`` the part spent continuing under the policy. ``horizon_s``: with a
        policy, how far its continuations run, s (the rest of the episode; ``None``: the options'
        ``horizon_s``; 0 or less: none runs, the episode is over).
        """
        started = time.perf_counter()
        state = self.frame(data)
        self.task.held = ModelCommand(
            ctrl=np.array(data.ctrl, dtype=float) if self._model.nu else None,
            mocap_pos=np.array(data.mocap_pos, dtype=float) if self._model.nmocap else None,
            mocap_quat=np.array(data.mocap_quat, dtype=float) if self._model.nmocap else None,
        )
        seed = int(self._seeds.spawn(1)[0].generate_state(1)[0])
        result: LiveScore
        tree_budget = self.tree_budget()
        if self.margin_model is not None:
            result = self.margin_model.score_state(self.task, state)
        else:
            feedback = self._feedback(horizon_s, float(data.time))
            with self.warning_log:  # MuJoCo's warnings of the trees, not MUJOCO_LOG.TXT in the cwd
                result = score_state(self.task, state, friction=self.friction, drive=self.drive, budget_s=tree_budget,
                    seed=seed, max_expansions=self.options.max_expansions, simulator=self.simulator,
                    config=self.options.config, feedback=feedback)  # fmt: skip
        seconds = time.perf_counter() - started
        if tree_budget is not None and self.margin_model is None:
            self._overruns.append(max(seconds - result.continuation_s - tree_budget, 0.0))
            del self._overruns[:-OVERRUN_WINDOW]
        return {
            "capture_score": float(result.capture),
            "success_score": float(result.success),
            "expansions": int(result.expansions),
            "nodes": int(result.nodes),
            "ms": 1000.0 * seconds,
            "stopped_by": result.stopped_by,
            "seed": seed,
            "rejected": int(result.rejected),
            "diverged": int(result.diverged),
            "tree_capture_score": float(result.tree_capture),
            "continuation_ms": 1000.0 * result.continuation_s,
        }

    def _feedback(self, horizon_s: float | None, time: float) -> FeedbackContinuation | None:
        """The continuation under the policy of a state at ``time`` (s, the environment's clock), ``horizon_s`` left.

        ``None`` without a policy or with no time left.
        """
        horizon = self.options.horizon_s if horizon_s is None else horizon_s
        if self.policy is None or horizon <= 0.0:
            return None
        controllers = replace(self.policy, start_time=time)
        return FeedbackContinuation(controllers, horizon, self.policy_period_s, self.options.continuation)

    def labels(self, data: mujoco.MjData) -> tuple[bool, bool]:
        """Whether the state in ``data`` is in the capture set and in the success set."""
        state = self.frame(data)
        return bool(self.task.is_captured(state)), bool(self.task.is_successful(state))


def _load_model(margin_model: Any, model_sha256: str) -> Any:
    """The learned margin to score with, refused when it was fitted on another compiled model.

    ``model_sha256`` is the hash of the model scored (:func:`~energy_margin.tasks.scene_model.model_hash`).
    """
    if margin_model is None:
        return None
    if isinstance(margin_model, str | Path):
        from energy_margin.learning.margin_file import load_margin_model

        margin_model = load_margin_model(margin_model, task_name="scene")
    if not hasattr(margin_model, "score_state"):
        raise EnergyMarginError(
            f"model must be a margin model file or a MarginModel, got {type(margin_model).__name__}"
        )
    config = getattr(margin_model, "task_config", None) or {}
    fitted_on = config.get("model_sha256") if isinstance(config, dict) else None
    if fitted_on and fitted_on != model_sha256:
        raise EnergyMarginError(
            f"the margin model was fitted on another compiled model (sha256 {str(fitted_on)[:12]}…, "
            f"this environment's {model_sha256[:12]}…)"
        )
    return margin_model
