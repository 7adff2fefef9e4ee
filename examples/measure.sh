#!/usr/bin/env bash
# Reproduce the figures of the examples' READMEs: each example on a 20 x 10 set, one worker.
#   bash examples/measure.sh OUT_DIR [ITERATIONS]
# ITERATIONS defaults to 300 (the analyzer's default); smaller sizes give a quick run (CI runs the
# examples in quick mode through tests/test_examples.py).
set -euo pipefail
out=${1:?usage: examples/measure.sh OUT_DIR [ITERATIONS] [TRAJECTORIES] [FRAMES]}
iterations=${2:-300}
trajectories=${3:-20}
frames=${4:-10}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
run() {  # name, then the command that writes the dataset
  local name=$1; shift
  "$@" --out "$out/$name" --overwrite
  /usr/bin/env time -f "$name: analyze %e s" energy-margin analyze "$out/$name" --expansions "$iterations" --workers 1 --seed 0 --overwrite
  energy-margin evaluate "$out/$name" | tee "$out/$name.evaluate.txt"
}
sets=(--trajectories "$trajectories" --frames "$frames" --seed 0)
run pushing_builtin energy-margin generate --task pushing --objects 10 "${sets[@]}"
run pushing_scene energy-margin generate --scene "$here/pushing/pushing.toml" "${sets[@]}"
python "$here/jaco/write_model.py"
run jaco energy-margin generate --scene "$here/jaco/jaco.toml" "${sets[@]}"
python "$here/record/simulate.py" --rollouts "$trajectories" --out "$out/logs"
run recorded energy-margin record --scene "$here/record/tabletop.toml" "$out"/logs/run_*.npz --frames "$frames"
