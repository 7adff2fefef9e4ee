"""What ``reproduce`` runs: the paper's sizes or the quick variant."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "TABLE_ONE_PROTOCOLS",
    "ReproduceConfig",
]

#: Perturbation protocols of Table I, in the order reported, and the suffix of their copies'
#: directory (``data/<task>-<n>-<suffix>/R``).
TABLE_ONE_PROTOCOLS = {"valid": "perturbed", "paper": "perturbed-paper"}


@dataclass(frozen=True)
class ReproduceConfig:
    """What ``reproduce`` runs.

    Attributes:
        quick: the small variant (minutes on 2 cores) instead of the paper's sizes.
        trajectories: roll-outs per Table I dataset.
        frames: frames per roll-out.
        iterations: EST iterations per frame.
        repeats: perturbed copies per Table I dataset.
        ablation_objects: numbers of objects of the Fig. 2 ablation (pushing).
        ablation_trajectories: roll-outs per ablation dataset.
        ablation_frames: frames per ablation roll-out.
        workers: parallel workers.
        engine: physics engine.
        seed: seed of every dataset, perturbation and analysis.
    """

    quick: bool = False
    trajectories: int = 20
    frames: int = 10
    iterations: int = 300
    repeats: int = 5
    ablation_objects: tuple[int, ...] = (3, 5, 7, 10, 20)
    ablation_trajectories: int = 20
    ablation_frames: int = 10
    workers: int = 2
    engine: str = "mujoco"
    seed: int = 0

    @classmethod
    def create(cls, *, quick: bool, workers: int, engine: str, seed: int) -> ReproduceConfig:
        """The full or quick configuration."""
        if quick:
            return cls(
                quick=True,
                trajectories=6,
                frames=5,
                iterations=100,
                repeats=2,
                ablation_trajectories=3,
                ablation_frames=4,
                workers=workers,
                engine=engine,
                seed=seed,
            )
        return cls(workers=workers, engine=engine, seed=seed)
