#!/usr/bin/env bash
# Runs reeb's CPU backend and the peers of ../shared/peers back to back, one
# JSON line per measurement, then a table of rates and a table of the ratios
# issue 14 asks for:
#
#   van der Pol S2 ((q, s) only, per-trajectory ε, dt = 0.01, 1000 steps,
#   final state only), f32 and f64, at each size of SIZES:
#     reeb (best kernels) vs C (-march=native) and JAX;
#     reeb with REEB_CPU_ISA=v3 vs C built for x86-64-v3 (AVX2 + FMA) and
#     JAX with XLA_FLAGS=--xla_cpu_max_isa=AVX2: the same instruction set on
#     every side, on any x86-64 with AVX2;
#   spin–orbit S2 ((q, p) only, the ensemble of `reeb bench --scenario
#   spin_orbit/s2`), 10⁵ trajectories: reeb vs the C/OpenMP and JAX peers.
#
#   bash scripts/compare_peers.sh [OUT.jsonl]
#
# Needs: the peers' venv (VENV, default /tmp/reeb-peers-venv, made by
# ../shared/peers/setup.sh) for JAX and numba, and gcc; REPEAT (default 3)
# and SIZES (default "100000 1000000") as environment variables.
set -uo pipefail
cd "$(dirname "$0")/.."
PEERS="$(cd ../shared/peers && pwd)"
VENV="${VENV:-/tmp/reeb-peers-venv}"
PY="$VENV/bin/python"
OUT="${1:-/tmp/reeb-compare-$(date +%Y%m%d-%H%M%S).jsonl}"
REPEAT="${REPEAT:-3}"
SIZES="${SIZES:-100000 1000000}"
: > "$OUT"
CBIN=/tmp/reeb-peers-vdp_s2_c
gcc -O3 -march=native -fopenmp -o "$CBIN" "$PEERS/vdp_s2.c" -lm
V3=""
if grep -qw avx2 /proc/cpuinfo && grep -qw fma /proc/cpuinfo; then
  V3=/tmp/reeb-peers-vdp_s2_c_v3
  gcc -O3 -march=x86-64-v3 -fopenmp -o "$V3" "$PEERS/vdp_s2.c" -lm
fi
SOBIN=/tmp/reeb-peers-spin_orbit_s2_c
gcc -O3 -march=native -fopenmp -o "$SOBIN" "$PEERS/spin_orbit_s2.c" -lm
cargo build --release -q

# reeb_row LABEL SCENARIO PRECISION N [ENV=VALUE]: one reeb measurement.
reeb_row() {
  local label=$1 scenario=$2 p=$3 n=$4
  env ${5:-} ./target/release/reeb bench --backend cpu --scenario "$scenario" --precision "$p" \
    --n "$n" --steps 1000 --repeats "$REPEAT" --threads 2 --json /tmp/reeb-one.jsonl > /dev/null
  sed "s/^{/{\"label\": \"$label\", \"model\": \"${scenario%%/*}\",/" /tmp/reeb-one.jsonl >> "$OUT"
}
# peer_row LABEL MODEL COMMAND...: one peer measurement (a JSON line on stdout).
peer_row() {
  local label=$1 model=$2
  shift 2
  "$@" | sed "s/^{/{\"label\": \"$label\", \"model\": \"$model\",/" >> "$OUT"
}

for n in $SIZES; do
  for p in f32 f64; do
    echo "van der Pol n=$n $p" >&2
    reeb_row "reeb" van_der_pol/s2 "$p" "$n"
    peer_row "c" van_der_pol "$CBIN" --precision "$p" --n "$n" --steps 1000 --exp poly --repeat "$REPEAT"
    if [ -n "$V3" ]; then
      reeb_row "reeb v3" van_der_pol/s2 "$p" "$n" REEB_CPU_ISA=v3
      peer_row "c v3" van_der_pol "$V3" --precision "$p" --n "$n" --steps 1000 --exp poly --repeat "$REPEAT"
    fi
    if [ -x "$PY" ]; then
      peer_row "jax" van_der_pol "$PY" "$PEERS/vdp_s2.py" --impl jax --precision "$p" --n "$n" --steps 1000 --repeat "$REPEAT"
      # XLA capped at AVX2 too: the JAX a user of an AVX2-only machine runs.
      [ -n "$V3" ] && XLA_FLAGS=--xla_cpu_max_isa=AVX2 peer_row "jax v3" van_der_pol "$PY" "$PEERS/vdp_s2.py" --impl jax --precision "$p" --n "$n" --steps 1000 --repeat "$REPEAT"
      peer_row "numba" van_der_pol "$PY" "$PEERS/vdp_s2.py" --impl numba --block 32 --precision "$p" --n "$n" --steps 1000 --repeat "$REPEAT"
    fi
  done
done
for p in f32 f64; do
  echo "spin–orbit n=100000 $p" >&2
  reeb_row "reeb" spin_orbit/s2 "$p" 100000
  [ -n "$V3" ] && reeb_row "reeb v3" spin_orbit/s2 "$p" 100000 REEB_CPU_ISA=v3
  peer_row "c" spin_orbit "$SOBIN" --precision "$p" --n 100000 --steps 1000 --repeat "$REPEAT"
  if [ -x "$PY" ]; then
    peer_row "jax" spin_orbit "$PY" "$PEERS/spin_orbit_s2.py" --impl jax --precision "$p" --n 100000 --steps 1000 --repeat "$REPEAT"
  fi
done

python3 - "$OUT" <<'PYEOF'
import json, subprocess, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
rate = {(r["label"], r["model"], r["n"], r["precision"]): r["traj_steps_per_s"] for r in rows}
cpu = subprocess.run(["sh", "-c", "grep -m1 'model name' /proc/cpuinfo | cut -d: -f2"], capture_output=True, text=True).stdout.strip()
isa = "AVX-512" if "avx512f" in open("/proc/cpuinfo").read() else "AVX2" if " avx2" in open("/proc/cpuinfo").read() else "SSE"
print(f"CPU: {cpu} ({isa}), 2 threads, medians\n")
print("| model | implementation | n | precision | traj-steps/s |")
print("|---|---|---|---|---|")
for r in rows:
    print(f"| {r['model']} | {r['label']} | {r['n']} | {r['precision']} | {r['traj_steps_per_s']:.3e} |")
print("\n| ratio | n | precision | value | target |")
print("|---|---|---|---|---|")
def ratio(name, a, b, target):
    for (label, model, n, p) in sorted({k for k in rate if k[0] == a[0] and k[1] == a[1]}, key=lambda k: (k[2], k[3])):
        other = (b[0], b[1], n, p)
        if other in rate:
            v = rate[(label, model, n, p)] / rate[other]
            t = target_of(name, p, target)
            flag = "" if v >= t else "  (below)"
            print(f"| {name} | {n} | {p} | {v:.2f}{flag} | ≥ {t} |")
# Issue 34: f64 on AVX2 at ≥ 1.2× the C built for the same ISA.
def target_of(name, p, default):
    return 1.2 if name == "van der Pol: reeb v3 / C v3" and p == "f64" else default
ratio("van der Pol: reeb v3 / C v3", ("reeb v3", "van_der_pol"), ("c v3", "van_der_pol"), 0.9)
ratio("van der Pol: reeb / JAX", ("reeb", "van_der_pol"), ("jax", "van_der_pol"), 1.5)
ratio("van der Pol: reeb v3 / JAX v3", ("reeb v3", "van_der_pol"), ("jax v3", "van_der_pol"), 1.5)
ratio("van der Pol: reeb / C native", ("reeb", "van_der_pol"), ("c", "van_der_pol"), 0.9)
ratio("spin–orbit: reeb / C", ("reeb", "spin_orbit"), ("c", "spin_orbit"), 1.5)
ratio("spin–orbit: reeb / JAX", ("reeb", "spin_orbit"), ("jax", "spin_orbit"), 1.5)
ratio("spin–orbit: reeb v3 / C", ("reeb v3", "spin_orbit"), ("c", "spin_orbit"), 1.5)
ratio("spin–orbit: reeb v3 / JAX", ("reeb v3", "spin_orbit"), ("jax", "spin_orbit"), 1.5)
PYEOF
echo "rows: $OUT" >&2
