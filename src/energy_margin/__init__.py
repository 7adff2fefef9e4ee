"""energy-margin: frame-by-frame robustness of multi-object manipulation through energy margins.

The verbs a user calls are here, loaded on first use so that ``import energy_margin`` stays fast:

* :func:`generate` (``generate_dataset``) a dataset of a task's scripted roll-outs;
* :func:`analyze` its frames (trees of energy margins, ``scores.csv``), or :func:`analyze_frame` one;
* :func:`evaluate` the scores against the labels (an :class:`Evaluation`);
* :func:`calibrate` the likelihood's lambda on labelled frames (a ``Calibration``);
* :func:`learn` a margin model from generated and analysed sets (a ``LearnResult``);
* :func:`design_search` a task's tool by its margin (a ``DesignSearchResult``) or
  :func:`design_sweep` a grid of designs (a ``SweepResult``);
* :func:`score_state` one live state within a latency budget, or a user's running MuJoCo model
  with :class:`LiveModelScorer`;
* :func:`perturb_dataset` and :func:`compare_perturbed` for perception noise.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from energy_margin import _moved
from energy_margin._lazy import lazy_getattr
from energy_margin._version import __version__

_moved.install()

if TYPE_CHECKING:
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
    from energy_margin.analysis.live import LiveScore, score_state
    from energy_margin.analysis.run import analyze
    from energy_margin.data.dataset import Dataset, load_dataset
    from energy_margin.data.generate import generate_dataset
    from energy_margin.design.search import design_search
    from energy_margin.design.search_result import DesignSearchResult
    from energy_margin.design.sweep import design_sweep
    from energy_margin.design.sweep_results import SweepResult
    from energy_margin.evaluation.calibration import calibrate
    from energy_margin.evaluation.metrics import Evaluation, evaluate
    from energy_margin.integrations.live_model import LiveModelScorer
    from energy_margin.learning.pipeline import LearnResult, learn_pipeline
    from energy_margin.robustness.compare import compare_perturbed
    from energy_margin.robustness.perturb import perturb_dataset
    from energy_margin.tasks import resolve_task
    from energy_margin.world.ellipsoid import Ellipsoid, min_volume_ellipsoid

    generate = generate_dataset
    learn = learn_pipeline

#: Public name -> (module, name there).
_LAZY = {
    "AnalyzerConfig": ("energy_margin.analysis.frame", "AnalyzerConfig"),
    "analyze": ("energy_margin.analysis.run", "analyze"),
    "analyze_frame": ("energy_margin.analysis.frame", "analyze_frame"),
    "Dataset": ("energy_margin.data.dataset", "Dataset"),
    "generate": ("energy_margin.data.generate", "generate_dataset"),
    "generate_dataset": ("energy_margin.data.generate", "generate_dataset"),
    "load_dataset": ("energy_margin.data.dataset", "load_dataset"),
    "evaluate": ("energy_margin.evaluation.metrics", "evaluate"),
    "Evaluation": ("energy_margin.evaluation.metrics", "Evaluation"),
    "calibrate": ("energy_margin.evaluation.calibration", "calibrate"),
    "learn": ("energy_margin.learning.pipeline", "learn_pipeline"),
    "learn_pipeline": ("energy_margin.learning.pipeline", "learn_pipeline"),
    "LearnResult": ("energy_margin.learning.pipeline", "LearnResult"),
    "design_search": ("energy_margin.design.search", "design_search"),
    "DesignSearchResult": ("energy_margin.design.search_result", "DesignSearchResult"),
    "design_sweep": ("energy_margin.design.sweep", "design_sweep"),
    "SweepResult": ("energy_margin.design.sweep_results", "SweepResult"),
    "score_state": ("energy_margin.analysis.live", "score_state"),
    "LiveScore": ("energy_margin.analysis.live", "LiveScore"),
    "LiveModelScorer": ("energy_margin.integrations.live_model", "LiveModelScorer"),
    "resolve_task": ("energy_margin.tasks", "resolve_task"),
    "Ellipsoid": ("energy_margin.world.ellipsoid", "Ellipsoid"),
    "min_volume_ellipsoid": ("energy_margin.world.ellipsoid", "min_volume_ellipsoid"),
    "perturb_dataset": ("energy_margin.robustness.perturb", "perturb_dataset"),
    "compare_perturbed": ("energy_margin.robustness.compare", "compare_perturbed"),
}

__getattr__ = lazy_getattr("energy_margin", _LAZY)

__all__ = [
    "AnalyzerConfig",
    "Dataset",
    "DesignSearchResult",
    "Ellipsoid",
    "Evaluation",
    "LearnResult",
    "LiveModelScorer",
    "LiveScore",
    "SweepResult",
    "__version__",
    "analyze",
    "analyze_frame",
    "calibrate",
    "compare_perturbed",
    "design_search",
    "design_sweep",
    "evaluate",
    "generate",
    "generate_dataset",
    "learn",
    "learn_pipeline",
    "load_dataset",
    "min_volume_ellipsoid",
    "perturb_dataset",
    "resolve_task",
    "score_state",
]
