"""The pipeline stages of the package, earliest first: a stage imports only earlier ones.

``tests/test_architecture.py`` checks the imports against this order and
``benchmarks/argument_trace.py`` counts the calls that go back up it; the modules outside every
stage are the foundations (``errors``, ``compat``, ``_lazy``, ...).
"""

from __future__ import annotations

__all__ = ["STAGES"]

STAGES = (
    "runs",
    "world",
    "sim",
    "tasks",
    "data",
    "planning",
    "analysis",
    "evaluation",
    "robustness",
    "learning",
    "control",
    "design",
    "experiments",
    "integrations",
    "report",
    "cli",
)
