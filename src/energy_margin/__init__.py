"""energy-margin: frame-by-frame robustness of multi-object manipulation through energy margins."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from energy_margin import _moved
from energy_margin._version import __version__

_moved.install()

if TYPE_CHECKING:
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
    from energy_margin.analysis.run import analyze
    from energy_margin.data.dataset import Dataset, load_dataset
    from energy_margin.data.generate import generate_dataset
    from energy_margin.evaluation.metrics import evaluate
    from energy_margin.robustness.compare import compare_perturbed
    from energy_margin.robustness.perturb import perturb_dataset
    from energy_margin.world.ellipsoid import Ellipsoid, min_volume_ellipsoid

_LAZY = {
    "AnalyzerConfig": "energy_margin.analysis.frame",
    "analyze": "energy_margin.analysis.run",
    "analyze_frame": "energy_margin.analysis.frame",
    "Dataset": "energy_margin.data.dataset",
    "generate": "energy_margin.data.generate",
    "generate_dataset": "energy_margin.data.generate",
    "load_dataset": "energy_margin.data.dataset",
    "evaluate": "energy_margin.evaluation.metrics",
    "Ellipsoid": "energy_margin.world.ellipsoid",
    "min_volume_ellipsoid": "energy_margin.world.ellipsoid",
    "perturb_dataset": "energy_margin.robustness.perturb",
    "compare_perturbed": "energy_margin.robustness.compare",
}


def __getattr__(name: str) -> Any:
    # Heavy modules (MuJoCo, scikit-learn) load on first use so `import energy_margin` stays fast.
    if name in _LAZY:
        import importlib

        module = importlib.import_module(_LAZY[name])
        return getattr(module, "generate_dataset" if name == "generate" else name)
    raise AttributeError(f"module 'energy_margin' has no attribute {name!r}")


__all__ = [
    "AnalyzerConfig",
    "Dataset",
    "Ellipsoid",
    "__version__",
    "analyze",
    "analyze_frame",
    "compare_perturbed",
    "evaluate",
    "generate",
    "generate_dataset",
    "load_dataset",
    "min_volume_ellipsoid",
    "perturb_dataset",
]
