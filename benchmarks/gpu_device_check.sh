#!/usr/bin/env bash
# The GPU engine's device check, in one run on a CUDA machine that reaches no package registry:
# install the wheels carried beside the tree, check parity against C MuJoCo on a small set, then
# time frames per second against the expansions per round and the objects per scene, with the
# GPU's memory, beside C MuJoCo on every CPU core of that machine. Results go under $OUT (or
# ./gpu-results), one JSON file per measurement, each written when it finishes.
#
# Wheels: WHEELS (default ./wheels) holds what `pip download -d wheels -c requirements.lock '.[gpu]'
# setuptools==80.9.0` fetches on a machine with the registries (Python 3.11, x86_64), less what the
# device's Python already has (the venv sees its site packages: numpy, scipy). The warp-lang wheel
# (149 MB) is larger than one carried tree (64 MiB): split it with
# `split -b 48M warp_lang-*.whl wheels/warp-part-` and carry the parts over successive calls (a
# warm machine keeps them); this script joins them.
#
#     bash benchmarks/gpu_device_check.sh                      # about 10 minutes on one H100/H200
#     DEVICE=cpu TRAJECTORIES=1 EXPANSIONS=30 bash benchmarks/gpu_device_check.sh   # its mechanics, on a CPU
set -euo pipefail
cd "$(dirname "$0")/.."
WHEELS=${WHEELS:-wheels}
OUT=${OUT:-gpu-results}
DEVICE=${DEVICE:-cuda}
TRAJECTORIES=${TRAJECTORIES:-3}
EXPANSIONS=${EXPANSIONS:-300}
mkdir -p "$OUT"
if ls "$WHEELS"/warp-part-* >/dev/null 2>&1; then
    cat "$WHEELS"/warp-part-* > "$WHEELS/warp_lang-1.19.0-py3-none-manylinux_2_28_x86_64.whl"
    rm "$WHEELS"/warp-part-*
fi
python3 -m venv --system-site-packages .venv-gpu
.venv-gpu/bin/pip install -q --no-index --find-links "$WHEELS" -e '.[gpu]' 2>&1 | tail -2
if [ "$DEVICE" = cuda ]; then
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv > "$OUT/gpu.csv" || true
fi
py=.venv-gpu/bin/python
# Parity: TRAJECTORIES roll-outs x 10 frames of pushing-10, 32 expansions a round, on both engines.
timeout 240 $py benchmarks/bench_gpu_engine.py --parity --device "$DEVICE" --trajectories "$TRAJECTORIES" \
    --expansions "$EXPANSIONS" --seed 700 --out "$OUT/gpu_parity_$DEVICE.json" || echo "parity: exit $?"
# Throughput: 2 roll-outs per object count, 32/100/300 expansions a round.
timeout 300 $py benchmarks/bench_gpu_engine.py --throughput --device "$DEVICE" --trajectories 2 --seed 701 \
    --expansions "$EXPANSIONS" --object-counts 5 10 20 --batches 32 100 300 \
    --out "$OUT/gpu_throughput_$DEVICE.json" || echo "throughput: exit $?"
# Parity with the fast contact model on both engines (no cylinder rims: the engines' contacts agree).
timeout 120 $py benchmarks/bench_gpu_engine.py --parity --device "$DEVICE" --contacts fast --trajectories "$TRAJECTORIES" \
    --expansions "$EXPANSIONS" --seed 700 --out "$OUT/gpu_parity_fast_$DEVICE.json" || echo "parity, fast contacts: exit $?"
ls -la "$OUT"
