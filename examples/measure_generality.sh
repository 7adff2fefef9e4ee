#!/usr/bin/env bash
# The table of docs/results/generality.md for one example: a 50 x 10 set of generation seed 202 from the scene
# file as written, the same trajectories with [perturbation] derive = true (settings derived from the
# scene) and without [perturbation] (the fixed defaults: 2 m/s^2 in x and y, 20 rad/s^2 about z, 0.1 s,
# lambda 5; docs/results/generality.md's rows were measured with the former 2 m/s^2 per axis and no torque),
# then calibrate and the paired verdicts (benchmarks/bench_generality.py), two workers.
#   bash examples/measure_generality.sh NAME SCENE.toml OUT_DIR [record]
# With `record`, the trajectories are examples/record/simulate.py roll-outs of seed 202 instead.
set -euo pipefail
name=${1:?usage: examples/measure_generality.sh NAME SCENE.toml OUT_DIR [record]}
scene=${2:?scene file}
out=${3:?output directory}/$name
mode=${4:-generate}
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
python "$here/benchmarks/scene_without_perturbation.py" "$scene" "$out/derived.toml" --derive
python "$here/benchmarks/scene_without_perturbation.py" "$scene" "$out/fixed.toml"
if [ "$mode" = record ]; then
  [ -d "$out/logs" ] || python "$here/examples/record/simulate.py" --rollouts 50 --seed 202 --out "$out/logs"
  [ -d "$out/file" ] || energy-margin record --scene "$scene" "$out"/logs/run_*.npz --frames 10 --out "$out/file"
  for variant in derived fixed; do
    [ -d "$out/$variant" ] || energy-margin record --scene "$out/$variant.toml" "$out"/logs/run_*.npz --frames 10 --out "$out/$variant"
  done
else
  for variant in file derived fixed; do
    toml=$scene; [ $variant != file ] && toml=$out/$variant.toml
    [ -d "$out/$variant" ] || energy-margin generate --scene "$toml" --trajectories 50 --frames 10 --seed 202 --out "$out/$variant"
  done
fi
energy-margin scene "$out/derived.toml" --no-picture | grep "perturbation"
python "$here/benchmarks/bench_generality.py" "$name" "$out/file" "$out/derived" --work "$out/work" --workers 2 --json "$out/row.json" \
  --variant "fixed defaults=$out/fixed"
