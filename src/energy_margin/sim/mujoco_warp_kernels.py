"""MuJoCo Warp's side of the ``mujoco-warp`` engine: Warp imported and quiet, and the engine's own kernels.

Importing Warp is slow and prints at its default level, so both happen on first use. The kernels
move a call's controls and results between the device arrays: :func:`engine_kernels` returns
``hold_controls`` (the step's command period's controls into MuJoCo Warp's data), ``keep_state``
(a world's state into the results, after each step or after its own last one) and ``tick`` (the
step counter on the device, so that one step is the same launches every time: a CUDA graph).
"""

from __future__ import annotations

from typing import Any

__all__ = ["engine_kernels", "load_warp"]


def load_warp() -> Any:
    """The ``warp`` module, initialised, reporting warnings only."""
    import warp as wp

    # Warp reports every module it loads at its default level; the engine's messages are its own.
    wp.config.log_level = getattr(wp, "LOG_WARNING", wp.config.log_level)
    wp.config.quiet = True
    wp.init()
    return wp


_DEFINED: dict[str, Any] = {}


def engine_kernels() -> dict[str, Any]:
    """The engine's own Warp kernels (defined once, on first use: importing Warp is slow)."""
    if _DEFINED:
        return _DEFINED
    wp = load_warp()

    @wp.kernel
    def hold_controls(
        clock: wp.array(dtype=int),  # type: ignore[valid-type]
        period: int,
        ctrl_seq: wp.array3d(dtype=float),  # type: ignore[valid-type]
        qfrc_seq: wp.array3d(dtype=float),  # type: ignore[valid-type]
        xfrc_seq: wp.array3d(dtype=float),  # type: ignore[valid-type]
        mocap_seq: wp.array3d(dtype=float),  # type: ignore[valid-type]
        ctrl: wp.array2d(dtype=float),  # type: ignore[valid-type]
        qfrc_applied: wp.array2d(dtype=float),  # type: ignore[valid-type]
        xfrc_applied: wp.array2d(dtype=wp.spatial_vector),  # type: ignore[valid-type]
        mocap_pos: wp.array2d(dtype=wp.vec3),  # type: ignore[valid-type]
        mocap_quat: wp.array2d(dtype=wp.quat),  # type: ignore[valid-type]
    ) -> None:
        w = wp.tid()
        t = clock[0] // period
        for i in range(ctrl.shape[1]):
            ctrl[w, i] = ctrl_seq[w, t, i]
        for i in range(qfrc_applied.shape[1]):
            qfrc_applied[w, i] = qfrc_seq[w, t, i]
        for b in range(xfrc_applied.shape[1]):
            xfrc_applied[w, b] = wp.spatial_vector(
                xfrc_seq[w, t, 6 * b],
                xfrc_seq[w, t, 6 * b + 1],
                xfrc_seq[w, t, 6 * b + 2],
                xfrc_seq[w, t, 6 * b + 3],
                xfrc_seq[w, t, 6 * b + 4],
                xfrc_seq[w, t, 6 * b + 5],
            )
        n = mocap_pos.shape[1]
        for b in range(n):
            mocap_pos[w, b] = wp.vec3(mocap_seq[w, t, 3 * b], mocap_seq[w, t, 3 * b + 1], mocap_seq[w, t, 3 * b + 2])
            at = 3 * n + 4 * b
            mocap_quat[w, b] = wp.quat(
                mocap_seq[w, t, at], mocap_seq[w, t, at + 1], mocap_seq[w, t, at + 2], mocap_seq[w, t, at + 3]
            )

    @wp.kernel
    def keep_state(
        clock: wp.array(dtype=int),  # type: ignore[valid-type]
        every_step: int,
        steps: wp.array(dtype=int),  # type: ignore[valid-type]
        time: wp.array(dtype=float),  # type: ignore[valid-type]
        qpos: wp.array2d(dtype=float),  # type: ignore[valid-type]
        qvel: wp.array2d(dtype=float),  # type: ignore[valid-type]
        act: wp.array2d(dtype=float),  # type: ignore[valid-type]
        out: wp.array3d(dtype=float),  # type: ignore[valid-type]
    ) -> None:
        w = wp.tid()
        t = clock[0]
        slot = t
        if every_step == 0:
            if steps[w] != t + 1:
                return
            slot = 0
        out[w, slot, 0] = time[w]
        nq = qpos.shape[1]
        nv = qvel.shape[1]
        for i in range(nq):
            out[w, slot, 1 + i] = qpos[w, i]
        for i in range(nv):
            out[w, slot, 1 + nq + i] = qvel[w, i]
        for i in range(act.shape[1]):
            out[w, slot, 1 + nq + nv + i] = act[w, i]

    @wp.kernel
    def tick(clock: wp.array(dtype=int)) -> None:  # type: ignore[valid-type]
        # (Warp resolves the annotations through the body's names: it must name wp.)
        if wp.tid() == 0:
            clock[0] = clock[0] + 1

    _DEFINED.update(hold_controls=hold_controls, keep_state=keep_state, tick=tick)
    return _DEFINED
