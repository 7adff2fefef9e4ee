"""Robustness to perception noise: perturbed copies inside the ellipsoid, Table I comparison."""

from energy_margin._moved import stage_getattr

__all__ = [
    "stage_getattr",
]

# `energy_margin.robustness` was a module in 0.1.0: its names still resolve, with a warning.
__getattr__ = stage_getattr(__name__)
