"""Every configuration dataclass declares each field's own check once, beside its default."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.control.mppi import ControllerConfig
from energy_margin.design.verification import EpisodeVerifier
from energy_margin.errors import Constraint, InvalidParameterError, field_constraint
from energy_margin.planning.tree import TreeBudget
from energy_margin.tasks.config import TaskConfig
from energy_margin.tasks.pushing_config import PushingConfig
from energy_margin.tasks.scene_task_config import SceneTaskConfig, design_config_class
from energy_margin.tasks.scooping_config import ScoopingConfig
from energy_margin.tasks.state_box import StateBox
from energy_margin.world.scene import Geom, RigidObject, Scene

CONFIGS: list[type] = [
    AnalyzerConfig,
    ControllerConfig,
    TaskConfig,
    PushingConfig,
    ScoopingConfig,
    SceneTaskConfig,
    design_config_class({"finger_gap": 0.01}),
    Scene,
    StateBox,
    EpisodeVerifier,
    TreeBudget,
]

#: Fields with no constraint of their own, and why: no number and no fixed set of choices, or a
#: value only checked against another field.
UNCONSTRAINED: dict[tuple[str, str], str] = {
    ("SceneTaskConfig", "scene_file"): "a path",
    ("SceneTaskConfig", "scene_sha256"): "a digest",
    ("SceneTaskConfig", "model_sha256"): "a digest",
    ("Scene", "objects"): "the objects themselves",
    ("Scene", "robot"): "a link tree",
    ("Scene", "statics"): "geoms, each checking itself",
    ("Scene", "robot_joint_names"): "derived, not an argument",
    ("StateBox", "low"): "checked against high (an infinite bound is none)",
    ("StateBox", "high"): "checked against low",
    ("StateBox", "source"): "words",
}


def _owner(config: type, name: str) -> str:
    for base in config.__mro__:
        if name in getattr(base, "__annotations__", {}):
            return base.__name__
    return config.__name__


@pytest.mark.parametrize("config", CONFIGS, ids=lambda config: config.__name__)
def test_every_field_declares_a_constraint_its_default_meets(config: type) -> None:
    for field in dataclasses.fields(config):
        constraint = field_constraint(config, field.name)
        if (_owner(config, field.name), field.name) in UNCONSTRAINED:
            assert constraint is None, (config.__name__, field.name)
            continue
        assert isinstance(constraint, Constraint), (config.__name__, field.name)
        if field.default is not dataclasses.MISSING:
            checked = constraint.check(field.name, field.default)
            assert checked == field.default or constraint.kind == "float", (config.__name__, field.name)


def test_a_subclass_that_changes_a_default_keeps_the_check() -> None:
    # PushingConfig and ScoopingConfig declare timestep (and ScoopingConfig duration) again.
    for make, name in [
        (lambda: PushingConfig(timestep=0.0), "timestep"),
        (lambda: ScoopingConfig(timestep=-0.001), "timestep"),
        (lambda: ScoopingConfig(duration=0.0), "duration"),
        (lambda: ScoopingConfig(likelihood_lambda=-1.0), "likelihood_lambda"),
        (lambda: PushingConfig(max_duration=0.0), "max_duration"),
    ]:
        with pytest.raises(InvalidParameterError) as caught:
            make()
        assert caught.value.parameter == name


def test_task_settings_are_still_coerced_to_their_defaults_types() -> None:
    config = PushingConfig(tine_count=3.0, object_mass=1, friction_range=[0.1, 0.2])  # type: ignore[arg-type]
    assert config.tine_count == 3 and isinstance(config.tine_count, int)
    assert config.object_mass == 1.0 and isinstance(config.object_mass, float)
    assert config.friction_range == (0.1, 0.2)
    assert ScoopingConfig(base_half_extents=[0.1, 0.02, 0.01]).base_half_extents == (0.1, 0.02, 0.01)  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError, match=r"^tine_count must be an integer, got 2\.5$"):
        PushingConfig(tine_count=2.5)  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError, match=r"^spawn_x must be a list of 2 numbers"):
        PushingConfig(spawn_x=(0.1,))  # type: ignore[arg-type]


def _scene(**changes: object) -> Scene:
    box = RigidObject("box", Geom("box", (0.1, 0.1, 0.1)), 1.0)
    return Scene(objects=(box,), robot=None, statics=(), **{"friction": 0.5, **changes})  # type: ignore[arg-type]


REFUSED: list[tuple[Callable[[], object], str, str]] = [
    (lambda: PushingConfig(object_radius=0.0), "object_radius", "must be a finite number > 0, got 0.0"),
    (lambda: PushingConfig(lateral_force=-0.1), "lateral_force", "must be a finite number >= 0, got -0.1"),
    (lambda: PushingConfig(pusher_face="round"), "pusher_face", "must be one of flat, v, arc, fork, got 'round'"),
    (lambda: PushingConfig(ground_contact="disc"), "ground_contact", "must be one of geometry, footprint"),
    (lambda: PushingConfig(tine_count=1), "tine_count", "must be an integer >= 2, got 1"),
    (
        lambda: PushingConfig(pusher_half_extents=(0.4, -0.1, 0.015)),
        "pusher_half_extents",
        "must be 3 finite numbers > 0, got (0.4, -0.1, 0.015)",
    ),
    (
        lambda: PushingConfig(workspace=(2.0, 1.0)),
        "workspace",
        "must be a (low, high) pair of finite numbers with low <= high, got (2.0, 1.0)",
    ),
    (
        lambda: PushingConfig(drive_factor=(-0.1, 1.0)),
        "drive_factor",
        "must be a (low, high) pair of finite numbers >= 0 with low <= high, got (-0.1, 1.0)",
    ),
    (
        lambda: ScoopingConfig(stiffness_range=(0.0, 10.0)),
        "stiffness_range",
        "must be a (low, high) pair of finite numbers > 0 with low <= high, got (0.0, 10.0)",
    ),
    (lambda: ScoopingConfig(recorded_waypoints=-2), "recorded_waypoints", "must be a non-negative integer, got -2"),
    (lambda: ScoopingConfig(recorded_waypoints=1), "recorded_waypoints", "must be 0 or at least 2, got 1"),
    (lambda: ScoopingConfig(lip_height=-0.001), "lip_height", "must be a finite number >= 0"),
    (lambda: ScoopingConfig(scoop_angle=2.0), "scoop_angle", "must lie within tip_limits"),
    (lambda: design_config_class({"gap": 0.01})(gap=float("inf")), "gap", "must be finite"),
    (lambda: _scene(friction=-0.1), "friction", "must be a finite number >= 0, got -0.1"),
    (lambda: _scene(timestep=0.0), "timestep", "must be a finite number > 0, got 0.0"),
    (lambda: _scene(gravity=(0.0, -9.81)), "gravity", "must be 3 finite numbers, got (0.0, -9.81)"),
    (lambda: _scene(integrator="RK4"), "integrator", "must be one of Euler, implicitfast, got 'RK4'"),
    (lambda: _scene(object_motion="planar"), "object_motion", "must be one of free, upright"),
    (lambda: _scene(contact_time_constant=float("nan")), "contact_time_constant", "must be a finite number"),
    (lambda: _scene(contact_time_constant=0.001), "contact_time_constant", "must be at least two time steps"),
    (lambda: _scene(ground_contact="footprint"), "ground_contact", "'footprint' needs object_motion 'upright'"),
    (lambda: _scene(lateral_contact="box"), "lateral_contact", "must be one of geometry, sphere"),
    (lambda: StateBox((0.0,) * 3, (1.0,) * 3, max_speed=-1.0), "max_speed", "must be a finite number > 0, got -1.0"),
    (lambda: EpisodeVerifier("mppi"), "policy", "must be one of scripted, task, got 'mppi'"),
    (lambda: TreeBudget(expansions=-1), "expansions", "must be a non-negative integer, got -1"),
    (lambda: TreeBudget(nodes=1.5), "nodes", "must be a non-negative integer, got 1.5"),  # type: ignore[arg-type]
    (lambda: TreeBudget(nodes=5, max_expansions=-1), "max_expansions", "must be a non-negative integer, got -1"),
    (lambda: TreeBudget(expansions=None, nodes=None), "expansions", "and nodes cannot both be None"),
]


@pytest.mark.parametrize(("make", "parameter", "reason"), REFUSED)
def test_a_value_outside_its_constraint_is_refused_naming_the_field(
    make: Callable[[], object], parameter: str, reason: str
) -> None:
    with pytest.raises(InvalidParameterError) as caught:
        make()
    assert caught.value.parameter == parameter
    assert reason in caught.value.reason


def test_values_inside_the_constraints_are_accepted() -> None:
    assert _scene(gravity=[0.0, 0.0, -1.0], contact_time_constant=0.02).gravity == [0.0, 0.0, -1.0]
    assert _scene(object_motion="upright", ground_contact="footprint", lateral_contact="sphere").n_objects == 1
    assert PushingConfig(spawn_x=(1.0, 1.0), pusher_face="fork", tine_count=2).spawn_x == (1.0, 1.0)
    assert ScoopingConfig(friction_range=(0.0, 0.0), recorded_waypoints=2).recorded_waypoints == 2
    assert StateBox((-float("inf"),) * 3, (float("inf"),) * 3, max_speed=1.0).max_speed == 1.0
    assert TreeBudget(expansions=None, nodes=0).node_capacity == 1
    with pytest.warns(DeprecationWarning):
        assert TreeBudget(expansions=None, max_iterations=7, nodes=100).expansion_limit == 7  # type: ignore[call-arg]


@pytest.mark.parametrize(
    ("constraint", "value", "result"),
    [
        (Constraint("floats", length=2), [1, 2.5], (1.0, 2.5)),
        (Constraint("floats", length=3, minimum=0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        (Constraint("range"), (-1.0, -1.0), (-1.0, -1.0)),
        (Constraint("range", minimum=0.0, maximum=1.0), (0.0, 1.0), (0.0, 1.0)),
        (Constraint("range", optional=True), None, None),
    ],
)
def test_a_numbers_constraint_accepts(constraint: Constraint, value: object, result: object) -> None:
    assert constraint.check("x", value) == result


@pytest.mark.parametrize(
    ("constraint", "value", "message"),
    [
        (Constraint("floats", length=2), (1.0,), "x must be 2 finite numbers, got (1.0,)"),
        (Constraint("floats", length=2), "ab", "x must be 2 finite numbers, got 'ab'"),
        (Constraint("floats", length=2), (1.0, float("nan")), "x must be 2 finite numbers, got (1.0, nan)"),
        (
            Constraint("floats", length=1, minimum=0.0, exclusive=True),
            [0.0],
            "x must be 1 finite numbers > 0, got [0.0]",
        ),
        (Constraint("floats", length=2), (True, 1.0), "x must be 2 finite numbers, got (True, 1.0)"),
        (Constraint("range"), (1.0, 0.0), "x must be a (low, high) pair of finite numbers with low <= high"),
        (Constraint("range", maximum=1.0), (0.0, 2.0), "x must be a (low, high) pair of finite numbers <= 1 with"),
        (Constraint("range"), (0.0, 1.0, 2.0), "x must be a (low, high) pair"),
        (Constraint("range"), None, "x must be a (low, high) pair"),
    ],
)
def test_a_numbers_constraint_refuses(constraint: Constraint, value: object, message: str) -> None:
    with pytest.raises(InvalidParameterError) as caught:
        constraint.check("x", value)
    assert str(caught.value).startswith(message)
    assert caught.value.parameter == "x"


@dataclasses.dataclass(frozen=True)
class _OwnConfig(TaskConfig):
    """A user's task configuration that checks its settings by hand in ``check``."""

    timestep: float = 0.01
    mass: float = 1.0
    extents: tuple[float, float] = (0.1, 0.1)
    speed: float = 0.0
    gap: tuple[float, float] = (0.0, 1.0)


def test_the_check_helpers_still_refuse_and_warn_that_constraints_replace_them() -> None:
    from energy_margin.tasks.config import require_non_negative, require_positive, require_ranges

    with pytest.warns(DeprecationWarning, match=r"constrained\(default, POSITIVE\)"):
        require_positive(_OwnConfig(), "mass", "extents")
    for helper, name, changes, reason in [
        (require_positive, "extents", {"extents": (0.1, 0.0)}, "must be > 0, got (0.1, 0.0)"),
        (require_non_negative, "speed", {"speed": -1.0}, "must be >= 0, got -1.0"),
        (require_ranges, "gap", {"gap": (1.0, 0.0)}, "must be (low, high) with low <= high"),
    ]:
        config = _OwnConfig(**changes)  # type: ignore[arg-type]
        with pytest.warns(DeprecationWarning, match="goes in 0.3"), pytest.raises(InvalidParameterError) as caught:
            helper(config, name)
        assert caught.value.parameter == name and reason in caught.value.reason


def test_a_subclass_that_changes_a_default_without_its_constraint_keeps_the_base_check() -> None:
    assert field_constraint(_OwnConfig, "timestep") is None
    assert _OwnConfig(timestep=0.02).timestep == 0.02
    with pytest.raises(InvalidParameterError, match=r"^timestep must be a finite number > 0, got 0\.0$"):
        _OwnConfig(timestep=0.0)
