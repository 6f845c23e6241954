#!/bin/bash
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-380}
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
nvidia-smi --query-gpu=timestamp,clocks.sm,utilization.gpu,power.draw --format=csv,noheader -lms 250 > $OUT/clocks.csv 2>&1 &
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda $OLDPWD/.dev/vdp_s2.cu && nvcc -O3 -arch=native --use_fast_math -o vdp_cuda_fast $OLDPWD/.dev/vdp_s2.cu; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
$B info | head -4
bn() { echo "## $(el)s $*"; timeout 60 $B bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 "$@" 2>&1 | grep -E "gpu:|error"; }
{
bn --steps 1000
bn --steps 10000
for x in exp fin expfin; do echo "REEB_X=$x"; REEB_X=$x bn --steps 10000; done
for wg in 64 128 256; do for pt in 1 2; do echo "WG=$wg PT=$pt"; REEB_GPU_WORKGROUP=$wg REEB_GPU_PER_THREAD=$pt bn --steps 10000 --repeats 3; done; done
} 2>&1 | tee $OUT/reeb.txt
wait; cat /tmp/nvcc.txt
echo "== t=$(el) cuda"
for st in 1000 10000; do for b in vdp_cuda vdp_cuda_fast; do for p in f32 f64; do timeout 60 /tmp/$b --precision $p --n 10000000 --steps $st --repeat 5; done; done; done 2>&1 | tee $OUT/peers.jsonl
echo "== t=$(el) jax"
for p in f32 f64; do PYTHONUNBUFFERED=1 timeout 90 python3 .dev/vdp_s2.py --impl jax --vmap --precision $p --n 10000000 --steps 10000 --repeat 3; done 2>&1 | grep -v Warning | tee -a $OUT/peers.jsonl
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R $B doctor --out $OUT/reeb-doctor.json 2>&1 | tee $OUT/doctor.txt; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
