#!/bin/bash
# Issue 35 point 6, fourth GPU session, call 3: the probe measuring each
# candidate twice over up to 2^16 steps, logged (REEB_GPU_PROBE_LOG), from a
# fresh cache; then the same bench from the cache it wrote, and the CUDA peer.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda "$OLDPWD/.dev/vdp_s2.cu"; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
bn() { echo "## t=$(el)s $*"; timeout 60 "$B" bench --backend gpu --scenario van_der_pol/s2 --n 10000000 "$@" 2>&1 | grep -E "gpu:|rror|note|probe"; }
{
echo "### tuned from a fresh cache, 10000 steps, probe logged"; REEB_GPU_PROBE_LOG=1 bn --precision f32,f64 --steps 10000 --repeats 3
timeout 60 "$B" info 2>&1 | grep -A3 "GPU tuning"
echo "### from the cache, 10000 steps"; bn --precision f32,f64 --steps 10000 --repeats 3
echo "### from the cache, 1000 steps (lengthened)"; bn --precision f32,f64 --steps 1000 --repeats 3
} 2>&1 | tee "$OUT/reeb.txt"
wait $NV; cat /tmp/nvcc.txt
for p in f32 f64; do timeout 30 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee "$OUT/peers.jsonl"
echo "== t=$(el) end"
