"""Every test expectation that differs between the MuJoCo and numpy releases the package supports.

Exact physics numbers hold for one MuJoCo build with one numpy on one CPU architecture, so each
table here is keyed by ``(MuJoCo release, numpy major version)``: MuJoCo 4.0.0 with numpy 2 (the
newest CI leg) and MuJoCo 3.3.0 with numpy 1 (the oldest, ``ci/oldest.txt``). MuJoCo 3.3's
contacts move the objects differently (a box's face contact carries half its depth, a cylinder's
line contact is one row, not two), and numpy 1's sums and norms differ in the last bits.
:func:`for_release` gives a test the installed pair's entry and skips it, naming the pairs known,
for any other.
"""

from __future__ import annotations

from typing import Any, TypeVar

import mujoco
import numpy as np
import pytest

from energy_margin.compat import format_version, mujoco_version, numpy_version

Release = tuple[tuple[int, int, int], int]
NEWEST: Release = ((4, 0, 0), 2)
OLDEST: Release = ((3, 3, 0), 1)

T = TypeVar("T")

#: A MuJoCo release other than the installed one: the version recorded in a file "written under
#: another MuJoCo" (3.3.0, or 3.2.7 where 3.3.0 is installed).
OTHER_MUJOCO = "3.2.7" if mujoco_version() == (3, 3, 0) else "3.3.0"


def for_release(table: dict[Release, T], what: str) -> T:
    """The entry of ``table`` for the installed MuJoCo and numpy; skips the test for another pair."""
    key = (mujoco_version(), numpy_version()[0])
    if key not in table:
        pairs = ", ".join(f"MuJoCo {format_version(m)} with numpy {n}" for m, n in table)
        pytest.skip(f"{what} are pinned for {pairs} only, not MuJoCo {mujoco.__version__} with numpy {np.__version__}")
    return table[key]


_CAPTURE_4 = [
    0.9990319675841871,
    1.0,
    1.0,
    0.9999999999999997,
    0.9999999999999999,
    0.9999999999999998,
    0.9999999999999999,
    0.9999999999999998,
]

#: tests/test_pinned_scores.py: the pushing capture scores (each list one CPU's), the pushing
#: success scores and the scooping capture scores.
PINNED_SCORES: dict[Release, dict[str, list[Any]]] = {
    NEWEST: {
        # The second list: an AMD EPYC (AVX2, no AVX-512), whose first score differs in its last bit.
        "pushing_capture": [_CAPTURE_4, [0.9990319675841872, *_CAPTURE_4[1:]]],
        "pushing_success": [
            [0.0, 0.0003826021273872315, 1.0, 0.9999999999999997, 0.0, 0.0, 0.8556170044439853, 0.9999999999999998]
        ],
        "scooping_capture": [0.0, 0.04012926724378537, 0.0, 0.0],
    },
    OLDEST: {
        # The second lists: an AMD EPYC (AVX2, no AVX-512), whose sums differ in their last bit.
        "pushing_capture": [
            [0.9990344872661369, 1.0, 1.0, 1.0, 1.0, 1.0, 0.9999999999999999, 1.0],
            [0.9990344872661368, 1.0, 1.0, 0.9999999999999999, 0.9999999999999999, 1.0, 0.9999999999999999, 1.0],
        ],
        "pushing_success": [
            [0.0, 0.001520292838181316, 1.0, 1.0, 0.0, 0.0, 0.8453752256940691, 1.0],
            [0.0, 0.0015202928381813164, 1.0, 0.9999999999999999, 0.0, 0.0, 0.8453752256940691, 1.0],
        ],
        "scooping_capture": [0.0, 0.0, 0.0, 0.0],
    },
}

#: tests/data/test_generate.py: the trajectories of seed 43's crowd of 20 cylinders that sink into
#: themselves and are drawn again (trajectory -> draws refused).
CROWD_REDRAWN: dict[Release, dict[str, int]] = {
    NEWEST: {"12": 1},
    OLDEST: {"2": 1, "3": 1},
}

#: tests/sim/test_lateral_contact.py: how far a cylinder's contact depth may be from its sphere
#: stand-in's, m, against another object and against a face (the pusher, the wall), and how far a
#: face contact's normal may be. The engine's convex pair is iterative; MuJoCo 3.3's stays within
#: its CCD tolerance (1e-6; normals measured within 2.7e-6).
LATERAL_TOLERANCE: dict[Release, dict[str, float]] = {
    NEWEST: {"object": 1e-7, "face": 1e-8, "face_normal": 1e-6},
    OLDEST: {"object": 1e-6, "face": 1e-6, "face_normal": 1e-5},
}
