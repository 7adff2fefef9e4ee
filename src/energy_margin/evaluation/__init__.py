"""Evaluation against ground truth: Average Precision, distance baselines, budget sweeps."""

__all__: list[str] = []
