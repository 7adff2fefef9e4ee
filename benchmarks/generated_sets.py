"""Fingerprints of the datasets ``reproduce`` generates: run under two versions to show they are the same.

Generates the Table I sets (pushing, 10 cylinders; scooping, 5 boxes) and the ablation's pushing
sets (3, 5, 7, 10, 20 cylinders) at ``reproduce``'s sizes and seed, and prints (and writes as
JSON) the SHA-256 of every array of each and the trajectories ``generate`` redrew.

    PYTHONPATH=OTHER_CHECKOUT/src python benchmarks/generated_sets.py --out before.json
    python benchmarks/generated_sets.py --out after.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import tempfile
from pathlib import Path

import numpy as np

from energy_margin.data.generate import generate_dataset
from energy_margin.report.config import ReproduceConfig

KEYS = ("object_pos", "object_quat", "object_vel", "robot_q", "robot_v", "frame_time", "captured", "in_success")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    config = ReproduceConfig()
    sets = [
        ("pushing", 10, config.n_trajectories, config.n_frames),
        ("scooping", 5, config.n_trajectories, config.n_frames),
    ]
    sets += [("pushing", n, config.ablation_n_trajectories, config.ablation_n_frames) for n in config.ablation_objects]
    result = {}
    with tempfile.TemporaryDirectory() as folder:
        for task, n_objects, trajectories, frames in sets:
            name = f"{task}-{n_objects} ({trajectories}x{frames}, seed {config.seed})"
            dataset = generate_dataset(
                task,
                n_objects=n_objects,
                n_trajectories=trajectories,
                n_frames=frames,
                seed=config.seed,
                out=Path(folder) / f"{task}-{n_objects}-{trajectories}",
            )
            digest = hashlib.sha256()
            for key in KEYS:
                digest.update(np.ascontiguousarray(dataset.arrays[key]).tobytes())
            redrawn = dataset.metadata.get("redrawn", {})
            draws = {index: (entry["draw"] if isinstance(entry, dict) else entry) for index, entry in redrawn.items()}
            result[name] = {"sha256": digest.hexdigest(), "redrawn": draws}
            print(f"{name:40s} {digest.hexdigest()[:16]}  redrawn {draws}", flush=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
