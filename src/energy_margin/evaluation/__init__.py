"""Evaluation against ground truth: Average Precision, distance baselines, budget sweeps."""
