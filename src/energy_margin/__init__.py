"""energy-margin: frame-by-frame robustness of multi-object manipulation through energy margins."""

from __future__ import annotations

__version__ = "0.1.0"

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from energy_margin.analysis import AnalyzerConfig, analyze, analyze_frame
    from energy_margin.dataset import Dataset, generate_dataset, load_dataset
    from energy_margin.ellipsoid import Ellipsoid, min_volume_ellipsoid
    from energy_margin.evaluate import evaluate
    from energy_margin.perturb import perturb_dataset
    from energy_margin.robustness import compare_perturbed

_LAZY = {
    "AnalyzerConfig": "energy_margin.analysis",
    "analyze": "energy_margin.analysis",
    "analyze_frame": "energy_margin.analysis",
    "Dataset": "energy_margin.dataset",
    "generate": "energy_margin.dataset",
    "generate_dataset": "energy_margin.dataset",
    "load_dataset": "energy_margin.dataset",
    "evaluate": "energy_margin.evaluate",
    "Ellipsoid": "energy_margin.ellipsoid",
    "min_volume_ellipsoid": "energy_margin.ellipsoid",
    "perturb_dataset": "energy_margin.perturb",
    "compare_perturbed": "energy_margin.robustness",
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
