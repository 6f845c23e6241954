#!/bin/bash
# Issue 35 point 6, third H200 session, call 1: finite blocks, forcing-free B piece, exp variants, tune, CUDA peer.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda $OLDPWD/.dev/vdp_s2.cu; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
bn() { echo "## t=$(el)s $*"; timeout 60 $B bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --steps 10000 --repeats 3 "$@" 2>&1 | grep -E "gpu:|rror"; }
{
for b in 1 4 2 8; do echo "### block $b"; REEB_GPU_FINITE_BLOCK=$b bn --precision f32,f64; done
echo "### block 4 nofb"; REEB_X=nofb REEB_GPU_FINITE_BLOCK=4 bn --precision f32,f64
echo "### block 1 nofb"; REEB_X=nofb REEB_GPU_FINITE_BLOCK=1 bn --precision f32,f64
for x in "nofb,hw2" "nofb,cexp" "nofb,rawexp" "nofb,cexp,nofin"; do echo "### block 4 $x"; REEB_X=$x REEB_GPU_FINITE_BLOCK=4 bn --precision f32; done
echo "### block 1 nofb,cexp"; REEB_X=nofb,cexp REEB_GPU_FINITE_BLOCK=1 bn --precision f32
echo "### t=$(el) tune"; timeout 60 $B tune --precision f32,f64 2>&1 | tail -12
} 2>&1 | tee $OUT/reeb.txt
wait $NV; cat /tmp/nvcc.txt
echo "== t=$(el) cuda"
for p in f32 f64; do timeout 60 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee $OUT/peers.jsonl
echo "== t=$(el) end"
