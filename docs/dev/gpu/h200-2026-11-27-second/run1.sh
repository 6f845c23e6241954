#!/bin/bash
# Issue 35 point 6, second H200 session: the rint/pow2 change against the old kernel, variants, peers, doctor.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-470}
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda $OLDPWD/.dev/vdp_s2.cu && nvcc -O3 -arch=native --use_fast_math -o vdp_cuda_fast $OLDPWD/.dev/vdp_s2.cu; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
timeout 60 $B info 2>&1 | head -12
bn() { echo "## t=$(el)s $*"; timeout 60 $B bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 "$@" 2>&1 | grep -E "gpu:|rror"; }
{
echo "### new kernel, default (steps 1000, lengthened)"; bn --steps 1000
for v in "new::" "old:round:portable" "newrint_oldpow2::portable" "oldrint_newpow2:round:" "nofinite:fin:" "builtinexp:exp:" "both:expfin:"; do
  IFS=: read name x p <<< "$v"; echo "### $name REEB_X=$x REEB_X_POW2=$p"
  REEB_X=$x REEB_X_POW2=$p bn --steps 10000 --repeats 3
done
} 2>&1 | tee $OUT/reeb.txt
wait $NV; cat /tmp/nvcc.txt
echo "== t=$(el) cuda"
for st in 1000 10000; do for b in vdp_cuda vdp_cuda_fast; do for p in f32 f64; do timeout 60 /tmp/$b --precision $p --n 10000000 --steps $st --repeat 5; done; done; done 2>&1 | tee $OUT/peers.jsonl
R=$(( DEADLINE - 60 - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R $B doctor --out $OUT/reeb-doctor.json 2>&1 | tee $OUT/doctor.txt; echo "doctor rc ${PIPESTATUS[0]}"
R=$(( DEADLINE - $(el) )); echo "== t=$(el) jax (timeout $R s)"
for p in f32 f64; do PYTHONUNBUFFERED=1 timeout $((R/2)) python3 .dev/vdp_s2.py --impl jax --vmap --precision $p --n 10000000 --steps 1000 --repeat 3; done 2>&1 | grep -v Warning | tee -a $OUT/peers.jsonl
echo "== t=$(el) end"
