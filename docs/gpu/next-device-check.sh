#!/bin/bash
# The next GPU session's check (issue 35, after the fourth session), as one
# call of the device tool: carry the stripped binary as .dev/reeb-gpu, the
# CUDA peer as .dev/vdp_s2.cu, and the Vulkan loader and glvnd debs as .gl/
# (README, "no Rust toolchain"); run with DEADLINE seconds of budget.
#   strip -o .dev/reeb-gpu target/release/reeb
#   cp ../shared/peers/vdp_s2.cu .dev/
# It measures what the fourth session could not: the probe taking blocks of 8
# steps on a hardware GPU without measuring them (the f64 probe of the fourth
# session, over 30 ms runs, ranked the blocks backwards and kept a test per
# step, 0.81x CUDA where blocks of 8 give 1.03x). Expect from a fresh cache
# blocks of 8 (or 4) in both precisions: f32 ~1.59e12, f64 ~5.3-5.6e11.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-300}
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda "$OLDPWD/.dev/vdp_s2.cu"; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
bn() { echo "## t=$(el)s $*"; timeout 90 "$B" bench --backend gpu --scenario van_der_pol/s2 --n 10000000 "$@" 2>&1 | grep -E "gpu:|rror|note|probe"; }
{
echo "### tuned from a fresh cache, probe logged"; REEB_GPU_PROBE_LOG=1 bn --precision f32,f64 --steps 10000 --repeats 3
timeout 60 "$B" info 2>&1 | grep -A3 "GPU tuning"
echo "### from the cache"; bn --precision f32,f64 --steps 10000 --repeats 3
for b in 1 8; do echo "### block $b"; REEB_GPU_FINITE_BLOCK=$b bn --precision f32,f64 --steps 10000 --repeats 3; done
# Wall time against kernel time of whole runs (10^7 trajectories, 10 000
# steps): the host's share (tables, buffers, read-back, sorting, writing
# the arrays), ~1 s per run in the first session's clock trace.
printf 'name = "wall"\nmodel = "van_der_pol"\n[params]\nepsilon = 1.0\nforcing_amplitude = 0.5\nforcing_frequency = 1.1\n[initial]\nq = { linspace = [0.5, 2.0, 10000000] }\ns = 0.0\n[integrator]\nscheme = "s2"\ndt = 0.01\nsteps = 10000\n[output]\nfinal = ["q", "s"]\n' > /tmp/wall.toml
for p in f32 f64; do echo "### wall, $p"; TIMEFORMAT="wall %R s"; time (timeout 90 "$B" run /tmp/wall.toml --backend gpu --precision $p --out /tmp/wall-$p 2>&1 | tail -1); grep -o '"integration_seconds"[^,]*' /tmp/wall-$p/summary.json; done
# Issue 33's point 5 on a hardware GPU: each chaos indicator against its
# plain run (README, "Chaos indicators"; lavapipe's numbers are there).
echo "### indicators' cost"; timeout 120 "$B" bench --indicators --backend gpu --repeats 3 --json "$OUT/indicators.jsonl"
# SALI and GALI_2 against the plain run of the same scene on a hardware GPU
# (10^6 van der Pol orbits x 10^4 S2 steps, f32, integration seconds).
for extra in "" "sali = true" "gali = { k = 2 }"; do
  printf 'name = "align"\nmodel = "van_der_pol"\n[params]\nepsilon = { linspace = [0.5, 2.0, 1000] }\n[initial]\nq = { linspace = [0.5, 2.5, 1000] }\n[integrator]\nscheme = "s2"\ndt = 0.01\nsteps = 10000\n[output]\nfinal = ["q"]\n%s\n[run]\nprecision = "f32"\n' "$extra" > /tmp/align.toml
  echo "### alignment: ${extra:-plain}"; timeout 60 "$B" run /tmp/align.toml --backend gpu --out /tmp/align 2>&1 | tail -1; grep -o '"integration_seconds"[^,]*' /tmp/align/summary.json
done
} 2>&1 | tee "$OUT/reeb.txt"
wait $NV; cat /tmp/nvcc.txt
for p in f32 f64; do timeout 30 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee "$OUT/peers.jsonl"
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R "$B" doctor --out "$OUT/reeb-doctor.json" 2>&1 | tee "$OUT/doctor.txt"; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
