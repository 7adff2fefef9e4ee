from __future__ import annotations

import math

import numpy as np
import pytest

from energy_margin.errors import InvalidParameterError
from energy_margin.world.scene import Geom, Joint, Link, RigidObject, Scene


def _object(name: str = "a") -> RigidObject:
    return RigidObject(name, Geom("sphere", (0.1,)), 1.0)


@pytest.mark.parametrize(
    ("shape", "size", "message"),
    [
        ("cone", (1.0,), "shape must be one of"),
        ("box", (1.0, 1.0), "must have 3 values"),
        ("cylinder", (1.0,), "must have 2 values"),
        ("sphere", (0.0,), "finite and positive"),
        ("box", (1.0, -1.0, 1.0), "finite and positive"),
        ("plane", (1.0, float("nan")), "finite and positive"),
    ],
)
def test_geom_rejects_bad_shapes_and_sizes(shape: str, size: tuple[float, ...], message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        Geom(shape, size)


def test_geom_volume_by_hand() -> None:
    assert Geom("box", (0.1, 0.2, 0.3)).volume() == pytest.approx(8 * 0.1 * 0.2 * 0.3)
    assert Geom("cylinder", (0.05, 0.015)).volume() == pytest.approx(math.pi * 0.05**2 * 0.03)
    assert Geom("sphere", (0.2,)).volume() == pytest.approx(4 / 3 * math.pi * 0.008)
    assert Geom("plane", (1.0, 1.0)).volume() == 0.0


def test_principal_inertia_by_hand() -> None:
    # Box of half extents (a, b, c): I_xx = m (b^2 + c^2) / 3 (full lengths 2a, 2b, 2c).
    assert Geom("box", (0.1, 0.2, 0.3)).principal_inertia(2.0) == pytest.approx(
        (2 * (0.04 + 0.09) / 3, 2 * (0.01 + 0.09) / 3, 2 * (0.01 + 0.04) / 3)
    )
    # Solid cylinder of radius r, height h: I_zz = m r^2 / 2, I_xx = m (3 r^2 + h^2) / 12.
    assert Geom("cylinder", (0.05, 0.015)).principal_inertia(0.2) == pytest.approx(
        (0.2 * (3 * 0.0025 + 0.03**2) / 12, 0.2 * (3 * 0.0025 + 0.03**2) / 12, 0.5 * 0.2 * 0.0025)
    )
    assert Geom("sphere", (0.1,)).principal_inertia(5.0) == pytest.approx((0.02, 0.02, 0.02))
    with pytest.raises(InvalidParameterError, match="plane has no inertia"):
        Geom("plane", (1.0, 1.0)).principal_inertia(1.0)


def test_rigid_object_inertia_uses_its_geom() -> None:
    obj = RigidObject("c", Geom("cylinder", (0.05, 0.015)), 0.2)
    assert obj.inertia == Geom("cylinder", (0.05, 0.015)).principal_inertia(0.2)


def _robot() -> Link:
    finger = Link("finger", (Geom("box", (0.01, 0.01, 0.01)),), 0.1, joints=(Joint("f", "slide", (1.0, 0.0, 0.0)),))
    tip = Link("tip", (Geom("sphere", (0.01,)),), 0.05, joints=(Joint("t", "hinge", (0.0, 0.0, 1.0)),))
    palm = Link(
        "palm",
        (Geom("box", (0.1, 0.1, 0.02)),),
        1.0,
        joints=(Joint("x", "slide", (1.0, 0.0, 0.0)), Joint("y", "slide", (0.0, 1.0, 0.0))),
        children=(finger, Link("wrist", (Geom("sphere", (0.02,)),), 0.1, children=(tip,))),
    )
    return palm


def test_robot_links_and_joint_names_are_depth_first() -> None:
    scene = Scene(objects=(_object(),), robot=_robot(), statics=(), friction=0.5)
    assert [link.name for link in scene.robot_links] == ["palm", "finger", "wrist", "tip"]
    assert scene.robot_joint_names == ("x", "y", "f", "t")
    assert scene.n_robot_dofs == 4


def test_scene_without_robot_has_no_dofs() -> None:
    scene = Scene(objects=(_object(),), robot=None, statics=(), friction=0.5)
    assert scene.robot_links == []
    assert scene.n_robot_dofs == 0
    assert scene.robot_joint_names == ()


def test_object_masses_and_inertias_arrays() -> None:
    objects = (
        RigidObject("a", Geom("sphere", (0.1,)), 1.0),
        RigidObject("b", Geom("box", (0.1, 0.2, 0.3)), 2.0),
    )
    scene = Scene(objects=objects, robot=None, statics=(), friction=0.2)
    assert scene.n_objects == 2
    np.testing.assert_array_equal(scene.object_masses, [1.0, 2.0])
    assert scene.object_inertias.shape == (2, 3)
    np.testing.assert_allclose(scene.object_inertias[1], objects[1].inertia)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"objects": ()}, "at least one object"),
        ({"friction": -0.1}, "friction"),
        ({"friction": float("nan")}, "friction"),
        ({"timestep": 0.0}, "timestep"),
        ({"timestep": float("inf")}, "timestep"),
        ({"object_motion": "planar"}, "object_motion"),
    ],
)
def test_scene_validation(kwargs: dict[str, object], message: str) -> None:
    values: dict[str, object] = {"objects": (_object(),), "robot": None, "statics": (), "friction": 0.5}
    values.update(kwargs)
    with pytest.raises(InvalidParameterError, match=message):
        Scene(**values)


def test_scene_is_immutable() -> None:
    scene = Scene(objects=(_object(),), robot=None, statics=(), friction=0.5)
    with pytest.raises(AttributeError):
        scene.friction = 0.1
