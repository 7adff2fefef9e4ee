#!/usr/bin/env bash
# Scores of the same frames with the energy-margin of BEFORE (a checkout's src folder) and this
# one, at the defaults: the example scenes (which now get max_speed 10 m/s where they leave it out,
# and the planar default perturbation where they leave a bound out) and the built-in tasks.
# Frames are generated once, by BEFORE (generation seed 300, used for nothing else), and analysed
# by both. Writes what it prints to OUT.
#
#   bash benchmarks/defaults_unchanged.sh BEFORE_SRC OUT
set -u
before=$1; out=$2
here=$(cd "$(dirname "$0")/.." && pwd)
python=${PYTHON:-$here/.venv/bin/python}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
{
  echo "# $(date -u +%FT%TZ); $("$python" -c 'import mujoco, numpy; print("MuJoCo", mujoco.__version__, "numpy", numpy.__version__)'); 3 trajectories x 4 frames, seed 300, default budget"
  for name in pushing scooping fetch gym_pusher jaco panda_tray planar_manipulator; do
    case $name in
      pushing) source=(--task pushing --objects 10) ;;
      scooping) source=(--task scooping --objects 5) ;;
      *) "$python" "$here/examples/$name/write_model.py" --out "$work/$name" > /dev/null
         cp "$here/examples/$name/$name.toml" "$work/$name/$name.toml"
         source=(--scene "$work/$name/$name.toml") ;;
    esac
    PYTHONPATH=$before "$python" -m energy_margin generate "${source[@]}" --trajectories 3 --frames 4 --seed 300 \
      --out "$work/$name-before" > /dev/null 2>&1 || { echo "$name: generate failed"; continue; }
    cp -r "$work/$name-before" "$work/$name-after"
    PYTHONPATH=$before "$python" -m energy_margin analyze "$work/$name-before" --workers 1 --seed 0 --no-progress > /dev/null 2>&1
    "$python" -m energy_margin analyze "$work/$name-after" --workers 1 --seed 0 --no-progress > /dev/null 2>&1
    "$python" - "$name" "$work/$name-before/scores.csv" "$work/$name-after/scores.csv" <<'PY'
import csv, sys
name, before, after = sys.argv[1:]
rows = [list(csv.DictReader(open(path))) for path in (before, after)]
same = all(
    a[key] == b[key] for a, b in zip(*rows, strict=True) for key in ("capture_score", "success_score", "nodes")
)
print(f"{name:20s} frames {len(rows[1]):3d}  scores and nodes identical: {same}")
PY
  done
} > "$out" 2>&1
cat "$out"
