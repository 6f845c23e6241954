#!/bin/bash
# Issue 35 point 6: reeb on an NVIDIA GPU against the CUDA and JAX peers, then `reeb doctor`.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-400}
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache RUST_BACKTRACE=1
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,memory.total --format=csv | tee /tmp/smi.txt
ldconfig -p | grep -i vulkan; ls /usr/share/vulkan/icd.d /etc/vulkan/icd.d /usr/local/nvidia/share/vulkan/icd.d 2>&1
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda $OLDPWD/.dev/vdp_s2.cu && nvcc -O3 -arch=native --use_fast_math -o vdp_cuda_fast $OLDPWD/.dev/vdp_s2.cu; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
cat /usr/share/vulkan/icd.d/nvidia_icd.json; VK_LOADER_DEBUG=error,warn timeout 60 $B info > /tmp/info.txt 2>&1
if ! grep -qi nvidia /tmp/info.txt; then
  echo "== no NVIDIA adapter at first; with VK_DRIVER_FILES"; cat /tmp/info.txt
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  timeout 60 $B info > /tmp/info.txt 2>&1
fi
cat /tmp/info.txt
echo "== t=$(el) tune"; timeout 90 $B tune 2>&1 | tee $OUT/tune.txt
echo "== t=$(el) bench"; timeout 120 $B bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 --json $OUT/bench.jsonl 2>&1 | tee /tmp/bench.txt
wait; cat /tmp/nvcc.txt
echo "== t=$(el) cuda"
for b in vdp_cuda vdp_cuda_fast; do for p in f32 f64; do timeout 60 /tmp/$b --precision $p --n 10000000 --steps 1000 --repeat 5; done; done 2>&1 | tee $OUT/peers.jsonl
echo "== t=$(el) jax"
for p in f32 f64; do PYTHONUNBUFFERED=1 timeout 90 python3 .dev/vdp_s2.py --impl jax --vmap --precision $p --n 10000000 --steps 1000 --repeat 3; done 2>&1 | grep -v Warning | tee -a $OUT/peers.jsonl
echo "== t=$(el) variants"
for wg in 64 256; do for pt in 1 2 4; do echo "WG=$wg PT=$pt"; REEB_GPU_WORKGROUP=$wg REEB_GPU_PER_THREAD=$pt timeout 40 $B bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 --repeats 3 2>&1 | grep -i van_der; done; done | tee $OUT/variants.txt
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R $B doctor --out $OUT/reeb-doctor.json 2>&1 | tee $OUT/doctor.txt; echo "doctor rc ${PIPESTATUS[0]}"
nvidia-smi --query-gpu=clocks.sm,temperature.gpu,power.draw --format=csv
echo "== t=$(el) end"
