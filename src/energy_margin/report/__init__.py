"""Results for people: figures, the HTML report and the paper's reproduction."""

from energy_margin._moved import stage_getattr

__all__ = [
    "stage_getattr",
]

# `energy_margin.report` was a module in 0.1.0: its names still resolve, with a warning.
__getattr__ = stage_getattr(__name__)
