#!/usr/bin/env bash
# Runs reeb's CPU backend and the peers of ../shared/peers back to back on
# the van der Pol S2 job ((q, s) only, per-trajectory ε, dt = 0.01, 1000
# steps, final state only), one JSON line per measurement, then a table.
#
#   bash scripts/compare_peers.sh [OUT.jsonl]
#
# Needs: the peers' venv (VENV, default /tmp/reeb-peers-venv, made by
# ../shared/peers/setup.sh or `python3 -m venv` + pip install of numpy, numba,
# jax[cpu] at the pinned versions) and gcc; REPEAT (default 3) and SIZES
# (default "100000 1000000") as environment variables.
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
cargo build --release -q
for n in $SIZES; do
  for p in f32 f64; do
    echo "n=$n $p" >&2
    ./target/release/reeb bench --backend cpu --scenario van_der_pol/s2 --precision "$p" --n "$n" --steps 1000 --repeats "$REPEAT" --threads 2 --json /tmp/reeb-one.jsonl > /dev/null
    sed 's/^{/{"impl": "reeb cpu",/' /tmp/reeb-one.jsonl >> "$OUT"
    "$CBIN" --precision "$p" --n "$n" --steps 1000 --exp poly --repeat "$REPEAT" | sed 's/^{/{"label": "c blocked, poly exp, no -ffast-math",/' >> "$OUT"
    if [ -x "$PY" ]; then
      "$PY" "$PEERS/vdp_s2.py" --impl jax --precision "$p" --n "$n" --steps 1000 --repeat "$REPEAT" | sed 's/^{/{"label": "jax",/' >> "$OUT"
      "$PY" "$PEERS/vdp_s2.py" --impl numba --block 32 --precision "$p" --n "$n" --steps 1000 --repeat "$REPEAT" | sed 's/^{/{"label": "numba --block 32",/' >> "$OUT"
      if [ "$n" -le 100000 ]; then
        "$PY" "$PEERS/vdp_s2.py" --impl numpy --precision "$p" --n "$n" --steps 1000 --repeat "$REPEAT" | sed 's/^{/{"label": "numpy",/' >> "$OUT"
      fi
    fi
  done
done
python3 - "$OUT" <<'PYEOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
key = lambda r: (r.get("n"), r.get("precision"))
reeb = {key(r): r["traj_steps_per_s"] for r in rows if r.get("impl") == "reeb cpu"}
print("| implementation | n | precision | traj-steps/s | reeb / it |")
print("|---|---|---|---|---|")
for r in rows:
    name = r.get("impl") if r.get("impl") == "reeb cpu" else r.get("label", r.get("impl"))
    rate = r["traj_steps_per_s"]
    print(f"| {name} | {r['n']} | {r['precision']} | {rate:.3e} | {reeb.get(key(r), float('nan')) / rate:.2f} |")
PYEOF
echo "rows: $OUT" >&2
