"""Time min_volume_ellipsoid on random point sets; prints a table (no asserts).

    python benchmarks/bench_ellipsoid.py [--out docs/figures/bench_ellipsoid.json]

For each dimension d, number of points n and stopping tolerance, 200 random normal point sets (20
for n > 100), each fitted once after one warm-up fit: the median and 95th percentile of the fit's
wall time and the median number of iterations. ``--out`` keeps the rows, the machine and the load
average before the run.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench_analysis import machine
from checkout import write_figures
from energy_margin.world.ellipsoid import min_volume_ellipsoid

CASES = ((2, 10), (3, 5), (3, 10), (2, 100), (3, 1000))
TOLERANCES = (1e-6, 1e-2)


def time_case(rng: np.random.Generator, d: int, n: int, tol: float) -> dict[str, Any]:
    """One row: fits of random ``n``-point sets in ``d`` dimensions at tolerance ``tol``."""
    sets = [rng.normal(size=(n, d)) for _ in range(200 if n <= 100 else 20)]
    min_volume_ellipsoid(sets[0], tol=tol)
    durations, iterations = [], []
    for points in sets:
        started = time.perf_counter()
        ellipsoid = min_volume_ellipsoid(points, tol=tol)
        durations.append(time.perf_counter() - started)
        iterations.append(ellipsoid.iterations)
    ms = np.array(durations) * 1e3
    return {
        "d": d,
        "n": n,
        "tol": tol,
        "sets": len(sets),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "iterations_median": float(np.median(iterations)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="results JSON")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    load_before = os.getloadavg()[0]
    print(f"machine: {machine()}, load average {load_before:.2f}")
    print(f"{'d':>2s} {'n':>5s} {'tol':>6s} {'median [ms]':>12s} {'p95 [ms]':>9s} {'iterations (median)':>20s}")
    rows = []
    for d, n in CASES:
        for tol in TOLERANCES:
            row = time_case(rng, d, n, tol)
            rows.append(row)
            print(
                f"{d:2d} {n:5d} {tol:6.0e} {row['median_ms']:12.3f} {row['p95_ms']:9.3f} "
                f"{row['iterations_median']:20.0f}"
            )
    write_figures(
        args.out,
        {
            "command": "python benchmarks/bench_ellipsoid.py --out FILE",
            "machine": machine(),
            "load_before": load_before,
            "rows": rows,
        },
    )


if __name__ == "__main__":
    main()
