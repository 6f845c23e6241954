#!/usr/bin/env bash
# What each observer costs on top of the step: integration seconds of one
# scene with each observer alone (and all together) against the plain run
# of the same scene, the median of REPEATS runs each.
#
#   scripts/dev/observer_cost.sh REEB [vdp|so] [cpu|gpu] [ORBITS] [STEPS] [REPEATS]
#
# vdp: van der Pol S2 f32 (ε over [0.5, 5], dt 0.01); so: spin–orbit S2 f64
# (p over [0.3, 1.9], dt 0.05). Defaults: 20000 orbits × 20000 steps, 3 runs.
# KEEP=DIR keeps each scene's last outputs in DIR/<scene> (to compare builds).
set -euo pipefail
reeb="$1"; which="${2:-vdp}"; backend="${3:-cpu}"
n="${4:-20000}"; steps="${5:-20000}"; repeats="${6:-3}"
dir="$(mktemp -d)"; trap 'rm -rf "$dir"' EXIT

case "$which" in
  vdp) model="van_der_pol"; precision="f32"; dt=0.01
       axes="[params]
epsilon = { linspace = [0.5, 5.0, $n] }
[initial]
q = 2.0
s = 0.0"
       final='["q", "s"]'; var="q"; avg='["q"]'; stop='"q > 1e6"' ;;
  so)  model="spin_orbit"; precision="f64"; dt=0.05
       axes="[params]
eccentricity = 0.06
epsilon = 0.045
[initial]
q = 0.0
p = { linspace = [0.3, 1.9, $n] }"
       final='["q", "p"]'; var="p"; avg='["p"]'; stop='"p > 1e6"' ;;
  *) sed -n 2,9p "$0"; exit 2 ;;
esac

scene() { # name, extra [output] lines
  cat > "$dir/$1.toml" <<EOF
name = "$1"
model = "$model"
$axes
[integrator]
scheme = "s2"
dt = $dt
steps = $steps
[output]
final = $final
$2
[run]
backend = "$backend"
precision = "$precision"
EOF
}

scene plain ""
scene cycle "cycle = { var = \"$var\", level = 1.0, skip = 0.5 }"
scene crossing "poincare = { crossing = \"$var\", value = 1.0, direction = \"up\", max_points = 200 }"
scene strobe "poincare = { period = 6.283185307179586, max_points = 200 }"
scene average "average = $avg"
scene stop "stop = $stop"
scene frames "trajectory = { every = 100 }"
scene together "cycle = { var = \"$var\", level = 1.0, skip = 0.5 }
poincare = { crossing = \"$var\", value = 1.0, direction = \"up\", max_points = 200 }
average = $avg
stop = $stop"

seconds() { # median integration seconds of scene $1
  for _ in $(seq "$repeats"); do
    rm -rf "$dir/out"
    "$reeb" run "$dir/$1.toml" --out "$dir/out" >/dev/null 2>&1
    grep -o '"integration_seconds": [0-9.e+-]*' "$dir/out/summary.json" | cut -d' ' -f2
    if [ -n "${KEEP:-}" ]; then mkdir -p "$KEEP"; rm -rf "${KEEP:?}/$1"; cp -r "$dir/out" "$KEEP/$1"; fi
  done | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'
}

echo "$which ($model S2 $precision, $backend): $n orbits × $steps steps, median of $repeats"
base="$(seconds plain)"
printf '%-10s %9.3f s\n' plain "$base"
for s in cycle crossing strobe average stop frames together; do
  t="$(seconds "$s")"
  printf '%-10s %9.3f s  %6.2f×\n' "$s" "$t" "$(echo "$t / $base" | bc -l)"
done
