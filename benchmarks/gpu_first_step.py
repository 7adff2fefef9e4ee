"""Where the ``mujoco-warp`` engine and C MuJoCo part: one frame's root, computed by both.

For one frame of each set (generated as ``bench_gpu_engine.py`` generates them), the frame's root
state goes through C MuJoCo's ``mj_forward`` and MuJoCo Warp's ``forward`` (CPU device), and this
prints and writes what each found: contacts per geom-type pair, the largest difference of the
constraint forces and of the accelerations (and the body whose degree of freedom it is), the
solver's iterations and tolerance, the rim angles of each engine's plane contacts of one object, and
how far one step moves the objects apart on the two engines, beside C MuJoCo from the same state
rounded to float32 (what float32 storage alone changes).

    python benchmarks/gpu_first_step.py --workdir /tmp/gpu-sets --out docs/figures/gpu_first_step.json
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.data.dataset import load_dataset
from energy_margin.runs.versions import engine_versions

SETS = ("pushing-10x10-700", "scooping-5x10-701")
TYPES = {int(value): name.removeprefix("mjGEOM_").lower() for name, value in mujoco.mjtGeom.__members__.items()}


def _pairs(model: mujoco.MjModel, geoms: np.ndarray) -> Counter[str]:
    return Counter("-".join(sorted(TYPES[int(model.geom_type[g])] for g in pair)) for pair in geoms)


def _rim_angles(model: mujoco.MjModel, data: Any, geom: int, points: np.ndarray) -> list[float]:
    """Angles (degrees, in [0, 360)) of contact points about the geom's centre, in the world's x-y plane."""
    centre = data.geom_xpos[geom]
    return sorted(round(float(np.degrees(np.arctan2(p[1] - centre[1], p[0] - centre[0])) % 360), 1) for p in points)


def first_step(name: str, workdir: Path, trajectory: int, frame: int) -> dict[str, Any]:
    import mujoco_warp as mjw
    import warp as wp

    dataset = load_dataset(workdir / name)
    task = dataset.task
    friction, drive = float(dataset.arrays["friction"][trajectory]), dataset.arrays["drive"][trajectory]
    simulator = task.make_simulator(dataset.n_objects, friction, drive)
    simulator.reset(dataset.frame(trajectory, frame))
    model, data = simulator.model, simulator.data  # type: ignore[attr-defined]
    mujoco.mj_forward(model, data)
    with wp.ScopedDevice("cpu"):
        device_model = mjw.put_model(model)
        device_data = mjw.put_data(model, data, nconmax=512, njmax=2048)
        mjw.forward(device_model, device_data)
        n = int(device_data.nacon.numpy()[0])
        geoms = device_data.contact.geom.numpy()[:n]
        points = device_data.contact.pos.numpy()[:n]
        qacc = device_data.qacc.numpy()[0]
        constraint = device_data.qfrc_constraint.numpy()[0]
        iterations = int(device_data.solver_niter.numpy()[0])
        tolerance = float(np.asarray(device_model.opt.tolerance.numpy()).ravel()[0])
    c_geoms = np.stack([data.contact.geom1[: data.ncon], data.contact.geom2[: data.ncon]], axis=1)
    c_pairs, w_pairs = _pairs(model, c_geoms), _pairs(model, geoms)
    dof = int(np.argmax(np.abs(data.qacc - qacc)))
    body = int(model.dof_bodyid[dof])
    # One object's contacts with a plane, if it has any: where on its rim each engine puts them.
    rims = {}
    planes = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE]
    for geom in range(model.ngeom):
        if not planes or geom in planes:
            continue
        mine_c = [i for i in range(data.ncon) if geom in c_geoms[i] and set(c_geoms[i].tolist()) & set(planes)]
        mine_w = [i for i in range(n) if geom in geoms[i] and set(geoms[i].tolist()) & set(planes)]
        if mine_c and mine_w:
            rims = {
                "geom": model.geom(geom).name,
                "type": TYPES[int(model.geom_type[geom])],
                "mujoco_degrees": _rim_angles(model, data, geom, data.contact.pos[mine_c]),
                "mujoco_warp_degrees": _rim_angles(model, data, geom, points[mine_w]),
            }
            break
    # One step from the root on both engines, and on C MuJoCo from the root rounded to float32.
    stepped = copy.copy(data)
    mujoco.mj_step(model, stepped)
    rounded = copy.copy(data)
    for field in ("qpos", "qvel", "act"):
        getattr(rounded, field)[:] = getattr(data, field).astype(np.float32)
    mujoco.mj_step(model, rounded)
    with wp.ScopedDevice("cpu"):
        mjw.step(device_model, device_data)
        warp_qpos = device_data.qpos.numpy()[0]
    where = simulator.index.pos_index.ravel()  # type: ignore[attr-defined]  # the objects' positions
    return {
        "set": name,
        "trajectory": trajectory,
        "frame": frame,
        "contacts": {"mujoco": int(data.ncon), "mujoco_warp": n},
        "contact_pairs": {
            pair: {"mujoco": c_pairs[pair], "mujoco_warp": w_pairs[pair]}
            for pair in sorted(set(c_pairs) | set(w_pairs))
        },
        "largest_constraint_force_difference": float(np.abs(data.qfrc_constraint - constraint).max()),
        "largest_acceleration_difference": float(np.abs(data.qacc - qacc)[dof]),
        "at_body": {
            "name": model.body(body).name,
            "mass_kg": float(model.body_mass[body]),
            "inertia_kg_m2": model.body_inertia[body].tolist(),
        },
        "solver": {
            "mujoco": {"iterations": int(data.solver_niter[0]), "tolerance": float(model.opt.tolerance)},
            "mujoco_warp": {"iterations": iterations, "tolerance": tolerance},
        },
        "plane_contact_rim": rims,
        "one_step_largest_position_difference_m": {
            "mujoco_warp": float(np.abs(stepped.qpos[where] - warp_qpos[where]).max()),
            "mujoco_float32_root": float(np.abs(stepped.qpos[where] - rounded.qpos[where]).max()),
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workdir", type=Path, default=Path("/tmp/gpu-sets"), help="the sets of bench_gpu_engine.py")
    parser.add_argument("--sets", nargs="+", default=list(SETS))
    parser.add_argument("--trajectory", type=int, default=2)
    parser.add_argument("--frame", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    results = [first_step(name, args.workdir, args.trajectory, args.frame) for name in args.sets]
    document = {
        "command": "python benchmarks/" + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "versions": engine_versions("mujoco-warp"),
        "frames": results,
    }
    print(json.dumps(document, indent=1))
    if args.out is not None:
        args.out.write_text(json.dumps(document, indent=2) + "\n")


if __name__ == "__main__":
    main()
