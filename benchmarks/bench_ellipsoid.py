"""Time min_volume_ellipsoid on random point sets; prints a table (no asserts)."""

from __future__ import annotations

import platform
import time

import numpy as np

from energy_margin.world.ellipsoid import min_volume_ellipsoid


def main() -> None:
    rng = np.random.default_rng(0)
    print(f"machine: {platform.machine()}, python {platform.python_version()}, numpy {np.__version__}")
    print(f"{'d':>2s} {'n':>5s} {'tol':>6s} {'median [ms]':>12s} {'p95 [ms]':>9s} {'iterations (median)':>20s}")
    for d, n in ((2, 10), (3, 5), (3, 10), (2, 100), (3, 1000)):
        for tol in (1e-6, 1e-2):
            sets = [rng.normal(size=(n, d)) for _ in range(200 if n <= 100 else 20)]
            min_volume_ellipsoid(sets[0], tol=tol)
            durations, iterations = [], []
            for points in sets:
                started = time.perf_counter()
                ellipsoid = min_volume_ellipsoid(points, tol=tol)
                durations.append(time.perf_counter() - started)
                iterations.append(ellipsoid.iterations)
            ms = np.array(durations) * 1e3
            print(
                f"{d:2d} {n:5d} {tol:6.0e} {np.median(ms):12.3f} {np.percentile(ms, 95):9.3f} "
                f"{np.median(iterations):20.0f}"
            )


if __name__ == "__main__":
    main()
