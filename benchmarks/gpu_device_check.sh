#!/usr/bin/env bash
# The GPU engine's device check, in one run on a CUDA machine that reaches no package registry:
# install the wheels carried beside the tree, check parity against C MuJoCo on a small set, then
# time frames per second against the expansions per round and the objects per scene, with the
# GPU's memory, beside C MuJoCo on every CPU core of that machine. Results go under $OUT (or
# ./gpu-results), one JSON file per measurement, written as each finishes.
#
# Wheels: WHEELS (default ./wheels) holds mujoco, mujoco-warp, warp-lang and their dependencies
# (`pip download -d wheels -c requirements.lock '.[gpu]'` on a machine with the registries). The
# warp-lang wheel (about 149 MB) is larger than one carried tree (64 MiB): split it there with
# `split -b 48M warp_lang-*.whl wheels/warp-part-` and carry the parts over successive calls; this
# script joins them.
#
#     bash benchmarks/gpu_device_check.sh            # about 10 minutes on one H100/H200
set -euo pipefail
cd "$(dirname "$0")/.."
WHEELS=${WHEELS:-wheels}
OUT=${OUT:-gpu-results}
mkdir -p "$OUT"
if ls "$WHEELS"/warp-part-* >/dev/null 2>&1; then
    cat "$WHEELS"/warp-part-* > "$WHEELS/warp_lang-1.19.0-py3-none-manylinux_2_28_x86_64.whl"
    rm "$WHEELS"/warp-part-*
fi
python3 -m venv .venv-gpu
.venv-gpu/bin/pip install -q --no-index --find-links "$WHEELS" -e '.[gpu]' 2>&1 | tail -2
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv > "$OUT/gpu.csv" || true
py=.venv-gpu/bin/python
# Parity: 3 roll-outs x 10 frames of pushing-10, 300 expansions, 32 a round, on both engines.
timeout 240 $py benchmarks/bench_gpu_engine.py --parity --device cuda --trajectories 3 --seed 700 \
    --out "$OUT/gpu_parity_cuda.json" || echo "parity: exit $?"
# Throughput: 2 roll-outs per object count, 32/100/300 expansions a round.
timeout 300 $py benchmarks/bench_gpu_engine.py --throughput --device cuda --trajectories 2 --seed 701 \
    --object-counts 5 10 20 --batches 32 100 300 --out "$OUT/gpu_throughput.json" || echo "throughput: exit $?"
ls -la "$OUT"
