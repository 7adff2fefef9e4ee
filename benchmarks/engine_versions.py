"""How far scores and AP move when the same frames are analysed under other MuJoCo versions.

The paper's sets are generated once (under the MuJoCo of the interpreter that runs ``prepare``);
each MuJoCo version then analyses its own copy of them (``analyze``, run by an interpreter with that
version installed); ``compare`` prints and writes the largest score change per set and the AP of
every question per version, against a reference version. ``benchmarks/engine_versions.sh`` makes
one virtual environment per version and runs the three steps.

    python benchmarks/engine_versions.py prepare --out runs/engine_versions
    python benchmarks/engine_versions.py analyze --out runs/engine_versions    # once per MuJoCo version
    python benchmarks/engine_versions.py compare --out runs/engine_versions --reference 4.0.0
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.cli import main as cli

REFERENCE_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "reference" / "energy_margin_workshop"
#: The sets: name -> generate arguments, or the authors' frames to import.
SETS = {
    "pushing-10": ["--task", "pushing", "--objects", "10"],
    "scooping-5": ["--task", "scooping", "--objects", "5"],
    "authors-planepush-10": None,
}
#: The questions of ``evaluate --json`` compared per version, by their JSON key.
QUESTIONS = {
    "capture AP, k=0": "capture_ap",
    "capture AP, k=2": "capture_ap_window2",
    "success AP, last 3 frames": "success_ap",
    "success AP, first half": "success_ap_first_half",
}


class RefusedError(Exception):
    """A command that exited with an error (its error line is the message)."""


def run_cli(arguments: list[str]) -> str:
    """Run one energy-margin command in this process; its stdout (exit code checked)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli(arguments)
    sys.stderr.write(err.getvalue())
    if code != 0:
        lines = [line for line in err.getvalue().splitlines() if "error" in line] or [f"exit code {code}"]
        raise RefusedError(lines[-1])
    return out.getvalue()


def prepare(out: Path, trajectories: int, frames: int, seed: int) -> None:
    """Generate (or import) every set once into ``out/frames``."""
    for name, arguments in SETS.items():
        target = out / "frames" / name
        if target.exists():
            continue
        if arguments is None:
            source = REFERENCE_DATA / "planepush-10objects"
            run_cli(["import-reference", str(source), "--out", str(target), "--no-scores"])
        else:
            sizes = ["--trajectories", str(trajectories), "--frames", str(frames), "--seed", str(seed)]
            run_cli(["generate", *arguments, *sizes, "--out", str(target)])
        print(f"prepared {target} (MuJoCo {mujoco.__version__})", flush=True)


def analyze(out: Path, workers: int, seed: int, iterations: int) -> None:
    """Analyse a copy of every set under this interpreter's MuJoCo (``out/mujoco-VERSION/SET``)."""
    # Another seed under the same version measures how far the tree's own randomness moves them.
    folder = out / (f"mujoco-{mujoco.__version__}" + (f"-seed{seed}" if seed else ""))
    for name in SETS:
        target = folder / name
        if (target / "scores.csv").exists() or (folder / f"{name}.refused").exists():
            continue
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(out / "frames" / name, target)
        started = time.perf_counter()
        settings = [
            "--expansions",
            str(iterations),
            "--workers",
            str(workers),
            "--seed",
            str(seed),
            "--engine",
            "mujoco",
            "--continuation",  # the tree's own success score, as the figures were measured
            "0",
        ]
        try:
            run_cli(["analyze", str(target), *settings, "--no-progress"])
        except RefusedError as refusal:
            # The set is refused under this version (e.g. its dataset check): recorded, not scored.
            (folder / f"{name}.refused").write_text(f"{refusal}\n")
            print(f"refused {target}: {refusal}", flush=True)
            continue
        print(f"analysed {target} in {time.perf_counter() - started:.0f} s", flush=True)


def _scores(path: Path) -> np.ndarray:
    from energy_margin.data.scores_file import load_scores

    scores = load_scores(path)
    return np.stack([scores["capture_score"], scores["success_score"]], axis=1)


def _aps(path: Path) -> dict[str, float]:
    result = json.loads(run_cli(["evaluate", str(path), "--json"]))
    return {question: float(result[key]) for question, key in QUESTIONS.items()}


def compare(out: Path, reference: str) -> None:
    """Print and write (``out/engine_versions.json``, ``.md``) score and AP changes against ``reference``."""
    versions = sorted(
        (p.name.removeprefix("mujoco-") for p in out.glob("mujoco-*") if p.is_dir()),
        key=lambda v: (tuple(int(x) for x in v.split("-")[0].split(".")), v),
    )
    if reference not in versions:
        raise SystemExit(f"no analysis under MuJoCo {reference} in {out} (have {', '.join(versions)})")
    results: dict[str, dict[str, dict[str, float]]] = {}
    for name in SETS:
        base = _scores(out / f"mujoco-{reference}" / name)
        results[name] = {}
        for version in versions:
            path = out / f"mujoco-{version}" / name
            refused = out / f"mujoco-{version}" / f"{name}.refused"
            if refused.exists():
                results[name][version] = {"refused": refused.read_text().strip()}  # type: ignore[dict-item]
                continue
            if not (path / "scores.csv").exists():
                continue
            change = np.abs(_scores(path) - base)
            results[name][version] = {
                "max_capture_change": float(change[:, 0].max()),
                "max_success_change": float(change[:, 1].max()),
                "frames": int(base.shape[0]),
                **_aps(path),
            }
    lines = [
        f"Scores of the same frames under each MuJoCo version against MuJoCo {reference} "
        "(frames generated once; 300 expansions, seed 0; a -seedN row: the reference version with another seed).",
        "",
        "| set | MuJoCo | frames | max Δ capture | max Δ success | " + " | ".join(QUESTIONS) + " |",
        "|---|---|---|---|---|" + "---|" * len(QUESTIONS),
    ]
    for name, rows in results.items():
        for version, row in rows.items():
            if "refused" in row:
                lines.append(f"| {name} | {version} | – | refused: {row['refused']} |" + " |" * (len(QUESTIONS) + 1))
                continue
            cells = [f"{row[q]:.3f} ({row[q] - rows[reference][q]:+.3f})" for q in QUESTIONS]
            lines.append(
                f"| {name} | {version} | {row['frames']} | {row['max_capture_change']:.3f} | "
                f"{row['max_success_change']:.3f} | " + " | ".join(cells) + " |"
            )
    text = "\n".join(lines) + "\n"
    (out / "engine_versions.json").write_text(json.dumps({"reference": reference, "sets": results}, indent=2) + "\n")
    (out / "engine_versions.md").write_text(text)
    print(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("step", choices=("prepare", "analyze", "compare"))
    parser.add_argument("--out", type=Path, default=Path("runs/engine_versions"))
    parser.add_argument("--trajectories", type=int, default=20)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference", default="4.0.0")
    args = parser.parse_args(argv)
    if args.step == "prepare":
        prepare(args.out, args.trajectories, args.frames, args.seed)
    elif args.step == "analyze":
        analyze(args.out, args.workers, args.seed, args.expansions)
    else:
        compare(args.out, args.reference)
    return 0


if __name__ == "__main__":
    sys.exit(main())
