#!/usr/bin/env bash
# The pushing scene file against the built-in pushing task: same sizes, seeds 0, 1, 2, one worker.
#   bash examples/pushing/compare.sh OUT_DIR [ITERATIONS]
set -euo pipefail
out=${1:?usage: examples/pushing/compare.sh OUT_DIR [ITERATIONS]}
iterations=${2:-300}
here=$(cd "$(dirname "$0")" && pwd)
for seed in 0 1 2; do
  energy-margin generate --task pushing --objects 10 --trajectories 20 --frames 10 --seed "$seed" --out "$out/builtin_$seed" --overwrite
  energy-margin generate --scene "$here/pushing.toml" --trajectories 20 --frames 10 --seed "$seed" --out "$out/scene_$seed" --overwrite
  for name in builtin scene; do
    /usr/bin/env time -f "${name}_$seed: analyze %e s" energy-margin analyze "$out/${name}_$seed" --expansions "$iterations" --workers 1 --seed "$seed" --overwrite
    energy-margin evaluate "$out/${name}_$seed" --json > "$out/${name}_$seed.json"
  done
done
