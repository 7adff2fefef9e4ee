#!/usr/bin/env bash
# A scene as a new user writes it with MuJoCo Menagerie's integrator options: examples/panda_tray
# with five boxes, implicitfast and a 2 ms step (the example itself uses the implicit integrator at
# 4 ms because boxes rocking on the turning tray now and then gain energy and fly off otherwise).
# Generates 30 trajectories x 10 frames for each generation seed with the energy-margin of BEFORE
# (a checkout's src folder, e.g. one without the roll-out tests) and checks them with this one,
# then generates the same with this one. Writes everything printed to OUT.
#
#   bash benchmarks/unstable_tray.sh BEFORE_SRC OUT [SEEDS...]
set -u
before=$1; out=$2; shift 2
seeds=${*:-200 201}
here=$(cd "$(dirname "$0")/.." && pwd)
python=${PYTHON:-$here/.venv/bin/python}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$python" "$here/examples/panda_tray/write_model.py" --out "$work/scene" > /dev/null
sed -e 's/^count = 4$/count = 5/' "$here/examples/panda_tray/panda_tray.toml" > "$work/scene/panda_tray.toml"
sed -i 's/<option timestep="0.004" integrator="implicit"\/>/<option timestep="0.002" integrator="implicitfast"\/>/' "$work/scene/panda_scene.xml"
{
  echo "# $(date -u +%FT%TZ); $("$python" -c 'import mujoco, numpy; print("MuJoCo", mujoco.__version__, "numpy", numpy.__version__)')"
  grep -n "count = \|<option" "$work/scene/panda_tray.toml" "$work/scene/panda_scene.xml" | sed "s|$work/||"
  for seed in $seeds; do
    echo "## seed $seed: before"
    PYTHONPATH=$before "$python" -m energy_margin generate --scene "$work/scene/panda_tray.toml" \
      --trajectories 30 --frames 10 --seed "$seed" --out "$work/before-$seed" 2>&1 | tail -3
    echo "## seed $seed: check (this version) of the set generated before"
    "$python" -m energy_margin check "$work/before-$seed" 2>&1 | tail -12
    echo "## seed $seed: after"
    "$python" -m energy_margin generate --scene "$work/scene/panda_tray.toml" \
      --trajectories 30 --frames 10 --seed "$seed" --out "$work/after-$seed" 2>&1 | tail -3
    if [ -f "$work/after-$seed/dataset.json" ]; then
      "$python" - "$work/after-$seed/dataset.json" <<'PY'
import collections, json, sys
meta = json.load(open(sys.argv[1]))
redrawn = meta.get("redrawn", {})
kinds = collections.Counter()
for entry in redrawn.values():
    for reason in entry["reasons"]:
        kinds[reason.split(": ", 1)[-1].split(" at ")[0].split(" moves")[0][:60]] += 1
print(f"trajectories redrawn: {len(redrawn)}; refused draws: {sum(len(e['reasons']) for e in redrawn.values())}")
for index, entry in list(redrawn.items())[:4]:
    print(f"  trajectory {index}, draw {entry['draw']}: {entry['reasons'][0]}")
PY
      "$python" -m energy_margin check "$work/after-$seed" 2>&1 | tail -2
    fi
  done
} > "$out" 2>&1
cat "$out"
