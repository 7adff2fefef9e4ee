"""Why the perturbed capture AP is lower on this project's sets: the perturbed frames' own capture test.

The figures of docs/results/robustness.md, "Why the perturbed capture AP is lower on this
project's sets: measured", items 1-3, on four 20 x 10 sets: the authors' pushing frames
(``ref-push10``, imported without their scores, this project's nominal push), ``push10``
(pushing 10 objects, generation seed 0), the authors' scooping frames (``ref-scoop5``, imported
with the import's 3 cm blades) and ``scoop5`` (scooping 5 objects, seed 0); five paper-protocol
copies of each (``perturb --protocol paper --repeats 5 --seed 0``).

* Item 2, no tree: per copy, the task's own capture test (``Task.is_captured``, the test that
  labels a recorded frame) applied to the perturbed frame itself: the share of the true set's
  capture-positive frames still captured, the share of its negatives now captured, and the AP
  (scikit-learn, as ``energy_margin.evaluation``) of that yes/no test against the true labels.
  Also push10's valid-protocol copy 1 (``perturb`` default protocol, seed 0).
* Item 3, pushing only: per frame, the probability that all n_o centres drawn uniformly inside
  the ellipse of the true centres (the fit and sampler ``perturb`` uses) fall inside the frame's
  capture region (``DRAWS`` draws per frame, seeded per frame), its mean over capture-positive and
  over capture-negative frames; the median distance of a positive frame's nearest object to the
  region's edge; the positive rate.
* Item 1, trees: copies analysed as Table I (``analyze --expansions 300 --seed 0 --continuation 0
  --capture-gate none``): the AP of a copy's capture scores against the copy's own labels (its
  own frames' capture test), and against the true labels; push10 copies 1-3 (``--push10-copies``)
  and the authors' pushing frames' copy 1.

Every set, copy and analysis is kept under ``--work`` (a run resumes); one worker throughout.

    python benchmarks/perturbed_capture.py --work runs/perturbed-capture --out docs/figures/perturbed_capture.json

Without ``../shared`` it prints one ``skip:`` line.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.evaluation.metrics import average_precision, score_grid
from energy_margin.robustness.resample import object_size
from energy_margin.world.ellipsoid import Ellipsoid, min_volume_ellipsoid
from engine_versions import REFERENCE_DATA
from results_document import document_head, energy_margin, work_arguments, write_document

__all__ = [
    "DRAWS",
    "SETS",
    "all_inside_odds",
    "copy_row",
    "copy_spans",
    "nearest_edge",
    "odds_summary",
    "own_labels",
    "span",
]

SEED = 0
REPEATS = 5
EXPANSIONS = 300
#: Draws of n_o centres per frame for item 3.
DRAWS = 4000
#: The sets: name -> what they are, and how they are made (``generate`` arguments or the authors' folder).
SETS: dict[str, dict[str, Any]] = {
    "ref-push10": {"label": "their pushing frames (ref-push10)", "folder": "planepush-10objects"},
    "push10": {"label": "push10 (this project)", "generate": ["--task", "pushing", "--objects", "10"]},
    "ref-scoop5": {
        "label": "their scooping frames (ref-scoop5, imported with 3 cm blades)",
        "folder": "gripper-5objects",
    },
    "scoop5": {"label": "scoop5 (this project)", "generate": ["--task", "scooping", "--objects", "5"]},
}
#: Item 3's sets (the pushing capture region has a signed distance to its edge).
PUSHING = ("ref-push10", "push10")
ANALYSE = ("analyze", "--expansions", str(EXPANSIONS), "--seed", str(SEED), "--continuation", "0")
TREE_OPTIONS = ("--capture-gate", "none", "--workers", "1", "--no-progress")


class Region(Protocol):
    """What item 3 asks of a capture region: membership and signed distance of positions (..., 3)."""

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray: ...

    def signed_distance(self, positions: np.ndarray) -> np.ndarray: ...


def span(values: list[float]) -> dict[str, Any]:
    """The smallest and largest of per-copy values, and the values (in copy order)."""
    floats = [float(v) for v in values]
    return {"min": min(floats), "max": max(floats), "values": floats}


def copy_row(true_labels: np.ndarray, own: np.ndarray) -> dict[str, Any]:
    """Item 2 for one copy: the share of positives still captured, of negatives now captured, the test's AP.

    Args:
        true_labels: the true set's capture labels, (T, K) bool.
        own: the task's capture test on each perturbed frame, (T, K) bool.
    """
    true_labels, own = np.asarray(true_labels, dtype=bool), np.asarray(own, dtype=bool)
    return {
        "still_captured": float(own[true_labels].mean()),
        "negatives_captured": float(own[~true_labels].mean()),
        "test_ap": average_precision(true_labels, own.astype(float)),
    }


def copy_spans(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Item 2's range over copies of each field of :func:`copy_row`."""
    return {key: span([row[key] for row in rows]) for key in ("still_captured", "negatives_captured", "test_ap")}


def own_labels(dataset: Dataset) -> np.ndarray:
    """The task's capture test on every frame of ``dataset`` (the test its labels were recorded with), (T, K)."""
    task = dataset.task
    return np.array(
        [
            [task.is_captured(dataset.frame(t, k)) for k in range(dataset.n_frames)]
            for t in range(dataset.n_trajectories)
        ]
    )


def all_inside_odds(
    region: Region, ellipse: Ellipsoid, heights: np.ndarray, draws: int, rng: np.random.Generator
) -> float:
    """The share of ``draws`` draws of n_o centres, uniform in the 2-D ``ellipse``, with every centre in ``region``.

    ``heights`` (n_o,) are the centres' heights (the planar draw keeps them).
    """
    n = len(heights)
    xy = ellipse.sample(rng, draws * n).reshape(draws, n, 2)
    positions = np.concatenate([xy, np.broadcast_to(heights[:, None], (draws, n, 1))], axis=-1)
    return float(np.all(region.contains(positions), axis=-1).mean())


def nearest_edge(region: Region, positions: np.ndarray) -> float:
    """Distance of the object nearest the region's edge, m (> 0 when every object is inside)."""
    return float(np.min(region.signed_distance(positions)))


def odds_summary(odds: np.ndarray, labels: np.ndarray, edge: np.ndarray) -> dict[str, float]:
    """Item 3 for one set: mean odds over positive and negative frames, median nearest edge of positives (cm)."""
    odds, labels, edge = (np.asarray(a).ravel() for a in (odds, labels, edge))
    labels = labels.astype(bool)
    return {
        "odds_positive": float(odds[labels].mean()),
        "odds_negative": float(odds[~labels].mean()),
        "edge_median_cm": float(np.median(edge[labels]) * 100.0),
        "positive_rate": float(labels.mean()),
    }


def _prepared(work: Path, name: str) -> Path:
    """The true set ``name`` under ``work`` (generated or imported when missing)."""
    out, made = work / name, SETS[name]
    if not (out / "frames.npz").exists():
        if "folder" in made:
            energy_margin("import-reference", str(REFERENCE_DATA / made["folder"]), "--out", str(out), "--no-scores")
        else:
            sizes = ("--trajectories", "20", "--frames", "10", "--seed", str(SEED))
            energy_margin("generate", *made["generate"], *sizes, "--out", str(out), "--overwrite")
    return out


def _copies(path: Path, protocol: str = "paper", repeats: int = REPEATS) -> list[Path]:
    """``perturb PATH --protocol P --repeats R --seed 0`` into ``PATH_P`` (kept when already there)."""
    out = path.with_name(f"{path.name}_{protocol}")
    copies = [out / str(r) for r in range(1, repeats + 1)]
    if not all((copy / "frames.npz").exists() for copy in copies):
        settings = ["--protocol", protocol, "--repeats", str(repeats), "--seed", str(SEED), "--out", str(out)]
        energy_margin("perturb", str(path), *settings, "--workers", "1", "--no-progress", "--overwrite")
    return copies


def capture_tests(work: Path) -> dict[str, Any]:
    """Item 2 for every set and copy, and for push10's valid-protocol copy 1 (``push10-valid-copy1``)."""
    found: dict[str, Any] = {}
    for name, made in SETS.items():
        path = _prepared(work, name)
        labels = load_dataset(path).capture_labels()
        copies = _copies(path)
        rows = [{"copy": r, **copy_row(labels, own_labels(load_dataset(c)))} for r, c in enumerate(copies, start=1)]
        found[name] = {
            "label": made["label"],
            "frames": int(labels.size),
            "positives": int(labels.sum()),
            # How often the task's test on the true frame agrees with the recorded label (their labels, imported).
            "true_test_agrees": int((own_labels(load_dataset(path)) == labels).sum()),
            "copies": rows,
            **copy_spans(rows),
        }
        print(f"{name}: capture test of {len(rows)} copies done", flush=True)
    push10 = _prepared(work, "push10")
    valid = _copies(push10, "valid", repeats=1)[0]
    found["push10-valid-copy1"] = {
        "label": "push10, valid protocol, copy 1",
        **copy_row(load_dataset(push10).capture_labels(), own_labels(load_dataset(valid))),
    }
    return found


def ellipse_odds(work: Path) -> dict[str, Any]:
    """Item 3 for the pushing sets: per frame the odds of an all-inside draw and the nearest edge, summarised."""
    found: dict[str, Any] = {}
    for name in PUSHING:
        dataset = load_dataset(_prepared(work, name))
        task, thickness = dataset.task, object_size(dataset)
        shape = (dataset.n_trajectories, dataset.n_frames)
        odds, edge = np.zeros(shape), np.zeros(shape)
        for index, (t, k) in enumerate(np.ndindex(*shape)):
            frame = dataset.frame(t, k)
            region = task.capture_region(frame)
            # The fit and the snapped copy ``perturb`` draws from; one stream per frame.
            ellipse = min_volume_ellipsoid(frame.object_pos[:, :2], min_thickness=thickness).snapped()
            rng = np.random.default_rng([SEED, index])
            odds[t, k] = all_inside_odds(region, ellipse, frame.object_pos[:, 2], DRAWS, rng)
            edge[t, k] = nearest_edge(region, frame.object_pos)
        found[name] = {**odds_summary(odds, dataset.capture_labels(), edge), "frames": int(odds.size)}
        print(f"{name}: ellipse odds done", flush=True)
    return found


def _analysed(copy: Path) -> Path:
    """``analyze COPY`` as Table I (300 expansions, seed 0, the tree's own success, no capture gate); resumed."""
    energy_margin(*ANALYSE, *TREE_OPTIONS, str(copy))
    return copy


def own_label_aps(work: Path, push10_copies: int) -> dict[str, Any]:
    """Item 1: the AP of analysed copies' capture scores against their own labels and against the true ones."""
    wanted = {"push10": range(1, push10_copies + 1), "ref-push10": range(1, 2)}
    found: dict[str, Any] = {}
    for name, numbers in wanted.items():
        path = _prepared(work, name)
        true_labels = load_dataset(path).capture_labels()
        copies = _copies(path)
        found[name] = {}
        for number in numbers:
            analysed = _analysed(copies[number - 1])
            copy = load_dataset(analysed)
            scores = score_grid(copy, load_scores(analysed), "capture_score")
            found[name][str(number)] = {
                "own_ap": average_precision(own_labels(copy), scores),
                "true_ap": average_precision(true_labels, scores),
            }
            print(f"{name} copy {number}: analysed, AP {found[name][str(number)]}", flush=True)
    every = [row["own_ap"] for rows in found.values() for row in rows.values()]
    return {"copies": found, "own_ap": span(every)}


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--push10-copies", type=int, default=3, help="push10 copies analysed for item 1 (1-3)")
    args = parser.parse_args()
    if not REFERENCE_DATA.is_dir():
        print(f"skip: the authors' data is not at {REFERENCE_DATA}")
        return
    started = time.perf_counter()
    found = {"sets": capture_tests(args.work), "ellipse_odds": ellipse_odds(args.work)}
    found["own_labels"] = own_label_aps(args.work, args.push10_copies)
    document = {
        **document_head("perturbed_capture.py"),
        "seed": SEED,
        "repeats": REPEATS,
        "draws": DRAWS,
        "expansions": EXPANSIONS,
        "workers": 1,
        "wall_s": round(time.perf_counter() - started, 1),
        **found,
    }
    write_document(args.out, document)
    print(json.dumps({key: found[key] for key in ("ellipse_odds", "own_labels")}, indent=1)[:4000])


if __name__ == "__main__":
    main()
