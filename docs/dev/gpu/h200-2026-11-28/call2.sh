#!/bin/bash
# Issue 35 point 6, fourth GPU session, call 2: the probe with its blocks
# always tried and compiles outside its budget, from a fresh cache; then the
# peers in the same run, and `reeb doctor` (f32 tolerance per exp form).
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-380}
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda "$OLDPWD/.dev/vdp_s2.cu"; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
bn() { echo "## t=$(el)s $*"; timeout 60 "$B" bench --backend gpu --scenario van_der_pol/s2 --n 10000000 "$@" 2>&1 | grep -E "gpu:|rror|note"; }
{
echo "### tuned from a fresh cache, 10000 steps"; bn --precision f32,f64 --steps 10000 --repeats 3
timeout 60 "$B" info 2>&1 | grep -A4 "GPU tuning"
echo "### tuned, 1000 steps (lengthened)"; bn --precision f32,f64 --steps 1000 --repeats 3
echo "### reeb tune (driver cache warm)"; timeout 60 "$B" tune --precision f32,f64 2>&1 | grep -E "van_der_pol|shape"
echo "### tuned again, 10000 steps"; bn --precision f32,f64 --steps 10000 --repeats 3
} 2>&1 | tee "$OUT/reeb.txt"
wait $NV; cat /tmp/nvcc.txt
echo "== t=$(el) cuda"
for p in f32 f64; do timeout 30 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee "$OUT/peers.jsonl"
echo "== t=$(el) jax"
export XLA_PYTHON_CLIENT_PREALLOCATE=false
for p in f32 f64; do timeout 90 python3 .dev/vdp_s2.py --impl jax --vmap --precision $p --n 10000000 --steps 1000 --repeat 3; done 2>&1 | grep -v Warning | tee -a "$OUT/peers.jsonl"
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R "$B" doctor --out "$OUT/reeb-doctor.json" 2>&1 | tee "$OUT/doctor.txt"; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
