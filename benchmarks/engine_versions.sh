#!/usr/bin/env bash
# The paper's sets generated once, analysed under several MuJoCo versions (benchmarks/engine_versions.py).
#   bash benchmarks/engine_versions.sh [OUT] [VERSION ...]
# One virtual environment per MuJoCo version under OUT/venvs: the package with the lock file's
# versions of everything but MuJoCo. The frames are generated under the first version given.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/engine_versions}
shift || true
versions=("${@:-4.0.0}")
[ "$#" -gt 0 ] || versions=(4.0.0 3.3.0 3.9.0 3.17.0 4.0.1)
mkdir -p "$out/venvs"
grep -v '^mujoco==' requirements.lock > "$out/venvs/constraints.txt"
for version in "${versions[@]}"; do
    venv="$out/venvs/mujoco-$version"
    if [ ! -x "$venv/bin/python" ]; then
        python3 -m venv "$venv"
        "$venv/bin/pip" install -q -c "$out/venvs/constraints.txt" . "mujoco==$version"
    fi
done
"$out/venvs/mujoco-${versions[0]}/bin/python" benchmarks/engine_versions.py prepare --out "$out"
for version in "${versions[@]}"; do
    "$out/venvs/mujoco-$version/bin/python" benchmarks/engine_versions.py analyze --out "$out"
done
"$out/venvs/mujoco-${versions[0]}/bin/python" benchmarks/engine_versions.py compare --out "$out" --reference "${versions[0]}"
