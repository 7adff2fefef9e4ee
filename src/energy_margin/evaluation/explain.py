"""Why trajectories failed: which object left the capture region or missed the success region, when and where.

A trajectory fails when its success label is false (not every object, or fewer than the success
set's ``at_least``, in the success region at the last frame). For each failed trajectory,
:func:`explain_failures` tests every object of every recorded frame against the regions the labels
were computed with (the capture region built from that frame, the success region at it) and reports

* each object's first frame outside the capture region (``left_capture``; at frame 0 the object
  started outside), and
* each object outside the success region at the last frame (``missed_success``),

with the frame's time (s) and the object's position (m, world frame) there. A set that needs only
``at_least`` objects inside (:class:`~energy_margin.tasks.region_sets.AtLeast`) is tested object
by object on its region, and the explanation says how many objects the set needs.

Everything comes from ``frames.npz`` (positions, velocities, orientations, frame times, the
recorded ``captured`` labels) and the task the dataset records; no physics is run.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.runs.results import TypedResult
from energy_margin.tasks.region_sets import AtLeast
from energy_margin.tasks.region_types import Region
from energy_margin.world.state import FrameState

__all__ = [
    "LEFT_CAPTURE",
    "MISSED_SUCCESS",
    "FailureExplanation",
    "ObjectEvent",
    "event_words",
    "explain_failures",
    "format_explanations",
    "object_membership",
]

#: The kind of an object's first frame outside the capture region.
LEFT_CAPTURE = "left_capture"
#: The kind of an object outside the success region at the last frame.
MISSED_SUCCESS = "missed_success"


@dataclass(frozen=True, kw_only=True)
class ObjectEvent(TypedResult):
    """One object outside a region at one frame.

    Attributes:
        kind: ``"left_capture"`` (its first frame outside the capture region) or
            ``"missed_success"`` (outside the success region at the last frame).
        object: the object's index (0-based, the dataset's object order).
        name: the object's name in the task's scene.
        frame: the frame's index within the trajectory.
        time_s: the frame's time, s.
        position: the object's position there, (x, y, z) m, world frame.
    """

    kind: str
    object: int
    name: str
    frame: int
    time_s: float
    position: tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class FailureExplanation(TypedResult):
    """The account of one failed trajectory.

    Attributes:
        trajectory: the trajectory's index.
        capture_lost_frame: the first frame whose recorded capture label is false, ``None`` when
            every frame is captured.
        capture_needed: objects the capture set needs inside (``at_least``, else every object).
        success_needed: objects the success set needs inside.
        events: the objects' exits, ordered by frame, then kind, then object.
    """

    trajectory: int
    capture_lost_frame: int | None
    capture_needed: int
    success_needed: int
    events: tuple[ObjectEvent, ...]

    def to_dict(self) -> dict[str, Any]:
        """The explanation as JSON-compatible values (each event a dictionary, positions lists)."""
        values = super().to_dict()
        values["events"] = [{**event.to_dict(), "position": list(event.position)} for event in self.events]
        return values

    @classmethod
    def from_dict(cls, values: Any) -> FailureExplanation:
        """The explanation of a dictionary written by :meth:`to_dict`."""
        events = tuple(
            ObjectEvent(**{**event, "position": tuple(event["position"])}) for event in values.get("events", ())
        )
        names = {field.name for field in dataclasses.fields(cls)}
        return cls(**{**{k: v for k, v in values.items() if k in names}, "events": events})


def object_membership(region: Region, frame: FrameState) -> tuple[np.ndarray, int]:
    """Which objects of ``frame`` lie in ``region``, shape (n,) bool, and how many the region needs inside.

    An :class:`AtLeast` set is unwrapped: its region is tested object by object and the count it
    needs is returned; any other region needs every object. Orientations go to a region that uses them.
    """
    n = frame.object_pos.shape[0]
    needed = n
    if isinstance(region, AtLeast):
        needed = region.count
        region = region.region
    if getattr(region, "uses_orientation", False):
        inside = region.contains(frame.object_pos, frame.object_vel, quaternions=frame.object_quat)  # type: ignore[call-arg]
    else:
        inside = region.contains(frame.object_pos, frame.object_vel)
    return np.broadcast_to(np.asarray(inside, dtype=bool), (n,)).copy(), needed


def _event(dataset: Dataset, kind: str, names: list[str], trajectory: int, frame: int, obj: int) -> ObjectEvent:
    position = dataset.arrays["object_pos"][trajectory, frame, obj]
    return ObjectEvent(
        kind=kind,
        object=obj,
        name=names[obj],
        frame=frame,
        time_s=float(dataset.arrays["frame_time"][trajectory, frame]),
        position=(float(position[0]), float(position[1]), float(position[2])),
    )


def _object_names(dataset: Dataset) -> list[str]:
    """The objects' names in the task's scene (``object<i>`` where it names them not one by one)."""
    arrays = dataset.arrays
    scene = dataset.task.build_scene(dataset.n_objects, float(arrays["friction"][0]), arrays["drive"][0])
    names = [str(obj.name) for obj in scene.objects]
    if len(names) != dataset.n_objects or len(set(names)) != len(names):
        names = [f"object{i}" for i in range(dataset.n_objects)]
    return names


def _explain(dataset: Dataset, trajectory: int, names: list[str]) -> FailureExplanation:
    task = dataset.task
    last = dataset.n_frames - 1
    events: list[ObjectEvent] = []
    left: set[int] = set()
    capture_needed = dataset.n_objects
    for index in range(dataset.n_frames):
        frame = dataset.frame(trajectory, index)
        inside, capture_needed = object_membership(task.capture_region(frame), frame)
        for obj in np.flatnonzero(~inside):
            if int(obj) not in left:
                left.add(int(obj))
                events.append(_event(dataset, LEFT_CAPTURE, names, trajectory, index, int(obj)))
    final = dataset.frame(trajectory, last)
    inside, success_needed = object_membership(task.success_region_at(final), final)
    events.extend(_event(dataset, MISSED_SUCCESS, names, trajectory, last, int(obj)) for obj in np.flatnonzero(~inside))
    lost = np.flatnonzero(~dataset.arrays["captured"][trajectory])
    return FailureExplanation(
        trajectory=trajectory,
        capture_lost_frame=int(lost[0]) if lost.size else None,
        capture_needed=capture_needed,
        success_needed=success_needed,
        events=tuple(sorted(events, key=lambda event: (event.frame, event.kind, event.object))),
    )


def explain_failures(dataset: Dataset) -> tuple[FailureExplanation, ...]:
    """The account of every failed trajectory of ``dataset``, in trajectory order.

    Args:
        dataset: a loaded dataset; its task's regions decide membership as they decided the labels.

    Returns:
        One :class:`FailureExplanation` per trajectory whose success label is false.

    """
    failed = np.flatnonzero(~dataset.success_labels())
    if failed.size == 0:
        return ()
    names = _object_names(dataset)
    return tuple(_explain(dataset, int(trajectory), names) for trajectory in failed)


def event_words(event: ObjectEvent) -> str:
    """What happened, in words: ``left the capture region`` (``started outside ...`` at frame 0) or ``missed ...``."""
    if event.kind != LEFT_CAPTURE:
        return "missed the success region"
    return "started outside the capture region" if event.frame == 0 else "left the capture region"


def _needs(needed: int, n_objects: int) -> str:
    return "every object" if needed >= n_objects else f"at least {needed} of {n_objects} objects"


def format_explanations(explanations: tuple[FailureExplanation, ...] | list[dict[str, Any]], n_objects: int) -> str:
    """Lines of text for the failed trajectories (or their dictionaries), one block per trajectory."""
    items = [e if isinstance(e, FailureExplanation) else FailureExplanation.from_dict(e) for e in explanations]
    if not items:
        return "failed trajectories: none"
    lines = [f"failed trajectories: {len(items)}"]
    for item in items:
        lost = (
            "captured at every frame"
            if item.capture_lost_frame is None
            else f"capture lost at frame {item.capture_lost_frame}"
        )
        lines.append(
            f"trajectory {item.trajectory}: {lost}; capture needs {_needs(item.capture_needed, n_objects)}, "
            f"success {_needs(item.success_needed, n_objects)}"
        )
        for event in item.events:
            what = event_words(event)
            x, y, z = event.position
            who = f"object {event.object}"
            if event.name != f"object{event.object}":
                who = f"{event.name} ({who})"
            lines.append(
                f"  {who} {what} at frame {event.frame} (t = {event.time_s:.3f} s) at ({x:.3f}, {y:.3f}, {z:.3f}) m"
            )
        if not item.events:
            lines.append("  no object outside either region at the recorded frames")
    return "\n".join(lines)
