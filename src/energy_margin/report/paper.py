"""The paper's reported values (Table I and Fig. 2), printed beside the reproduced ones."""

from __future__ import annotations

from typing import Any

__all__ = [
    "PAPER_FIG_2",
    "PAPER_TABLE_I",
]

#: The paper's Table I and Fig. 2 values, printed beside ours.
PAPER_TABLE_I: dict[str, dict[str, Any]] = {
    "pushing": {
        "n_objects": 10,
        "capture_ap": 1.00,
        "capture_ap_perturbed": (0.96, 0.01),
        "capture_score_error": (-0.04, 0.32),
        "success_ap": 0.98,
        "success_ap_perturbed": (0.97, 0.04),
        "success_score_error": (-0.04, 0.16),
    },
    "scooping": {
        "n_objects": 5,
        "capture_ap": 0.96,
        "capture_ap_perturbed": (0.79, 0.03),
        "capture_score_error": (-0.00, 0.11),
        "success_ap": 1.00,
        "success_ap_perturbed": (0.98, 0.02),
        "success_score_error": (-0.01, 0.13),
    },
}
PAPER_FIG_2: dict[int, dict[str, Any]] = {
    3: {"runtime": (0.37, 0.13), "capture_ap": 0.99, "success_ap": 1.00},
    5: {"runtime": (0.66, 0.39), "capture_ap": 0.99, "success_ap": 0.99},
    7: {"runtime": (0.81, 0.39), "capture_ap": 0.99, "success_ap": 0.99},
    10: {"runtime": (1.20, 0.46), "capture_ap": 0.98, "success_ap": 1.00},
}
