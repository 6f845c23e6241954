#!/bin/bash
# The next GPU session's check (issue 35 point 6), as one call of the device
# tool: carry the stripped binary as .dev/reeb-gpu, the CUDA peer as
# .dev/vdp_s2.cu, and the Vulkan loader and glvnd debs as .gl/ (README,
# "no Rust toolchain"); run with DEADLINE seconds of budget.
#   strip -o .dev/reeb-gpu target/release/reeb
#   cp ../shared/peers/vdp_s2.cu .dev/
# It measures what the third session could not: the committed kernel (the
# probe's blocks of 4 or 8 steps per finite test; the f32 exp from the
# adapter's exp2, which `reeb info` and the doctor's `exp` rows check)
# against REEB_GPU_EXP=exact and the CUDA peer, then `reeb doctor`.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-380}
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda "$OLDPWD/.dev/vdp_s2.cu"; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
timeout 60 "$B" info 2>&1 | head -8
bn() { echo "## t=$(el)s $*"; timeout 60 "$B" bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 "$@" 2>&1 | grep -E "gpu:|rror|note"; }
{
echo "### tuned, 10000 steps"; bn --steps 10000 --repeats 3
echo "### tuned, 1000 steps (lengthened)"; bn --steps 1000
echo "### REEB_GPU_EXP=exact, 10000 steps"; REEB_GPU_EXP=exact bn --steps 10000 --repeats 3 --precision f32
} 2>&1 | tee "$OUT/reeb.txt"
wait $NV; cat /tmp/nvcc.txt
for p in f32 f64; do timeout 30 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee "$OUT/peers.jsonl"
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R "$B" doctor --out "$OUT/reeb-doctor.json" 2>&1 | tee "$OUT/doctor.txt"; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
