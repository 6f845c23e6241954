#!/bin/bash
# The next GPU session's check (issue 35 point 6), as one call of the device
# tool: carry the stripped binary as .dev/reeb-gpu, the peers as .dev/vdp_s2.cu
# and .dev/vdp_s2.py, and the Vulkan loader and glvnd debs as .gl/ (README,
# "no Rust toolchain"); run with DEADLINE seconds of budget.
#   strip -o .dev/reeb-gpu target/release/reeb
#   cp ../shared/peers/vdp_s2.cu ../shared/peers/vdp_s2.py .dev/
# It measures what the last session could not: blocks of steps with one
# finite test each (REEB_GPU_FINITE_BLOCK) against a test every step, then
# what the tuning probe chooses, the peers, and `reeb doctor`.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-450}
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda "$OLDPWD/.dev/vdp_s2.cu"; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
bn() { echo "## t=$(el)s $*"; timeout 60 "$B" bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 "$@" 2>&1 | grep -E "gpu:|rror"; }
{
for b in 1 4 2 8; do echo "### REEB_GPU_FINITE_BLOCK=$b"; REEB_GPU_FINITE_BLOCK=$b bn --steps 10000 --repeats 3; done
echo "### tuned (the probe's choice)"; "$B" tune --precision f32,f64 2>&1 | tail -12
bn --steps 1000
} 2>&1 | tee "$OUT/reeb.txt"
wait $NV; cat /tmp/nvcc.txt
for p in f32 f64; do timeout 60 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee "$OUT/peers.jsonl"
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R "$B" doctor --out "$OUT/reeb-doctor.json" 2>&1 | tee "$OUT/doctor.txt"; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
