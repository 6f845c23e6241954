#!/usr/bin/env bash
# Error against run time, reeb's schemes beside heyoka (Taylor method, LLVM,
# batch mode on every thread), measured in one run on this machine:
#
#   van der Pol      ../shared/peers/wp_heyoka.py (the peer's own script)
#   spin–orbit       scripts/wp_heyoka_models.py --model spin_orbit (hy.time)
#   perturbed Kepler scripts/wp_heyoka_models.py --model kepler
#
# and a chaos map, scripts/chaos_map_heyoka.py: the maximal Lyapunov
# exponent over the forced van der Pol cascade (A = ε = 5, CHAOS_N = 1000
# values of ω in [2.45, 2.47], t = CHAOS_T = 1500), reeb's exact tangent map
# of the step against heyoka's variational equations, at equal accuracy of
# λ₁ (CHAOS_MAP=0 leaves it out).
#
# each f64, 16 384 trajectories, t = 50, reeb over a ladder of steps per
# scheme, heyoka over a ladder of tolerances; then the tables of
# scripts/heyoka_table.py (reeb's fastest configuration at heyoka's error,
# and the fastest of each at 1e-2, 1e-6, 4e-10, 5e-13) and, with PNG set,
# the diagram.
#
#   bash scripts/compare_heyoka.sh [OUT.jsonl]        # PNG=docs/img/heyoka.png to draw
#
# Needs the peers' venv (VENV, default /tmp/reeb-peers-venv, made by
# ../shared/peers/setup.sh: heyoka 7.13.2, numpy; matplotlib for PNG).
# N (default 16384) and T (default 50) as environment variables.
set -euo pipefail
cd "$(dirname "$0")/.."
PEERS="$(cd ../shared/peers && pwd)"
VENV="${VENV:-/tmp/reeb-peers-venv}"
PY="$VENV/bin/python"
OUT="${1:-/tmp/reeb-heyoka-$(date +%Y%m%d-%H%M%S).jsonl}"
N="${N:-16384}"
T="${T:-50}"
TOLS="${TOLS:-1e-3,1e-6,1e-9,1e-12,1e-14}"
[ -x "$PY" ] || { echo "no venv at $VENV: run ../shared/peers/setup.sh" >&2; exit 1; }
cargo build --release -q
REEB="$PWD/target/release/reeb"

# A ladder of steps per scheme: each scheme from where it is barely useful
# to where round-off takes over.
ladder() { # SCHEME DT...
  local s=$1; shift
  for dt in "$@"; do printf '%s:%s,' "$s" "$dt"; done
}
LADDER="$(ladder s2 0.02 0.01 0.005 0.0025)$(ladder mclachlan4 0.08 0.04 0.02 0.01)"
LADDER+="$(ladder yoshida6a 0.05 0.025 0.0125)$(ladder kahanli6 0.2 0.1 0.05 0.025)"
LADDER+="$(ladder yoshida8d 0.05 0.025 0.0125)$(ladder kahanli8 0.2 0.1 0.05 0.025)"
LADDER+="$(ladder sofspa10 0.4 0.2 0.1 0.05)"
LADDER="${SCHEMES:-${LADDER%,}}"

: > "$OUT"
echo "van der Pol (wp_heyoka.py)" >&2
"$PY" "$PEERS/wp_heyoka.py" "$REEB" --n "$N" --t-end "$T" --tols "$TOLS" --schemes "$LADDER" \
  | grep '^{"impl"' | sed 's/^{/{"model": "van_der_pol", /' >> "$OUT"
for m in spin_orbit kepler; do
  echo "$m (wp_heyoka_models.py)" >&2
  "$PY" scripts/wp_heyoka_models.py "$REEB" --model "$m" --n "$N" --t-end "$T" --tols "$TOLS" \
    --schemes "$LADDER" | grep '^{"impl"' >> "$OUT"
done
CPU="$(lscpu | sed -n 's/^Model name: *//p' | head -1)"
ISA=AVX2; grep -qw avx512f /proc/cpuinfo && ISA=AVX-512
echo "results: $OUT ($CPU, $ISA, $(nproc) threads)"
"$PY" scripts/heyoka_table.py "$OUT" ${PNG:+--png "$PNG"} --cpu "$CPU, $ISA, $(nproc) threads"
if [ "${CHAOS_MAP:-1}" != 0 ]; then
  echo "chaos map (chaos_map_heyoka.py)" >&2
  "$PY" scripts/chaos_map_heyoka.py "$REEB" --n "${CHAOS_N:-1000}" --t-end "${CHAOS_T:-1500}"
fi
