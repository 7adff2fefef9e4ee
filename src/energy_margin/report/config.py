"""What ``reproduce`` runs: the paper's sizes or the quick variant."""

from __future__ import annotations

from dataclasses import dataclass

from energy_margin._renamed import renamed_fields

__all__ = [
    "TABLE_ONE_PROTOCOLS",
    "ReproduceConfig",
]

#: Perturbation protocols of Table I, in the order reported, and the suffix of their copies'
#: directory (``data/<task>-<n>-<suffix>/R``).
TABLE_ONE_PROTOCOLS = {"valid": "perturbed", "paper": "perturbed-paper"}


@renamed_fields(
    iterations="expansions",
    trajectories="n_trajectories",
    frames="n_frames",
    ablation_trajectories="ablation_n_trajectories",
    ablation_frames="ablation_n_frames",
)
@dataclass(frozen=True)
class ReproduceConfig:
    """What ``reproduce`` runs.

    Attributes:
        quick: the small variant (minutes on 2 cores) instead of the paper's sizes.
        n_trajectories: roll-outs per Table I dataset.
        n_frames: frames per roll-out.
        expansions: tree expansions per frame.
        repeats: perturbed copies per Table I dataset.
        ablation_objects: numbers of objects of the Fig. 2 ablation (pushing).
        ablation_n_trajectories: roll-outs per ablation dataset.
        ablation_n_frames: frames per ablation roll-out.
        workers: parallel workers.
        engine: physics engine.
        seed: seed of every dataset, perturbation and analysis.
    """

    quick: bool = False
    n_trajectories: int = 20
    n_frames: int = 10
    expansions: int = 300
    repeats: int = 5
    ablation_objects: tuple[int, ...] = (3, 5, 7, 10, 20)
    ablation_n_trajectories: int = 20
    ablation_n_frames: int = 10
    workers: int = 2
    engine: str = "mujoco"
    seed: int = 0

    @classmethod
    def create(cls, *, quick: bool, workers: int, engine: str, seed: int) -> ReproduceConfig:
        """The full or quick configuration."""
        if quick:
            return cls(
                quick=True,
                n_trajectories=6,
                n_frames=5,
                expansions=100,
                repeats=2,
                ablation_n_trajectories=3,
                ablation_n_frames=4,
                workers=workers,
                engine=engine,
                seed=seed,
            )
        return cls(workers=workers, engine=engine, seed=seed)
