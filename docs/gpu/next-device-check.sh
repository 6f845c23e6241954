#!/bin/bash
# The next GPU check, as one call of the device tool (at most 5 minutes):
# carry the stripped binary as .dev/reeb-gpu, the CUDA peer as
# .dev/vdp_s2.cu, and the Vulkan loader and glvnd debs as .gl/ (README,
# "no Rust toolchain"); run with DEADLINE seconds of budget.
#   strip -o .dev/reeb-gpu target/release/reeb
#   cp ../shared/peers/vdp_s2.cu .dev/
# First the whole run against the kernel (summary.json's timing by phase):
# 10^7 van der Pol orbits x 10^3 S2 steps in f32 (target: wall <= 1.25x the
# integration), 10^7 x 10^4 (target: whole-run rate >= 0.8x the kernel's),
# the same sweep in four chunks (timing.overlap: chunk k read back and
# written while k+1 integrates), what --backend auto chooses for it, and reeb bench's
# whole-run column. Then the probe taking blocks of 8 steps on a hardware
# GPU without measuring them (expect f32 ~1.59e12, f64 ~5.3-5.6e11), the
# chaos indicators' cost, SALI/GALI, the CUDA peer and reeb doctor.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-300}
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
(cd /tmp && nvcc -O3 -arch=native -o vdp_cuda "$OLDPWD/.dev/vdp_s2.cu"; echo nvcc rc $?) > /tmp/nvcc.txt 2>&1 &
NV=$!
bn() { echo "## t=$(el)s $*"; timeout 90 "$B" bench --backend gpu --scenario van_der_pol/s2 --n 10000000 "$@" 2>&1 | grep -E "gpu:|rror|note|probe"; }
phases() { python3 -c "import json,sys; s=json.load(open(sys.argv[1])); t=s['timing']; print({k: round(v, 4) for k, v in t.items()}, 'wall/integration %.2f' % (t['wall'] / max(t['integration'], 1e-9)), 'chunks', s['chunks']['count'])" "$1/summary.json"; }
sweep() { # steps, precision, extra run flags
  printf 'name = "sweep"\nmodel = "van_der_pol"\n[params]\nepsilon = { linspace = [0.1, 10.1, 10000000] }\n[initial]\nq = 2.0\ns = 0.0\n[integrator]\nscheme = "s2"\ndt = 0.01\nsteps = %s\n[output]\nfinal = ["q", "s"]\n[run]\nprecision = "%s"\n' "$1" "$2" > /tmp/sweep.toml
  shift 2; rm -rf /tmp/sweep-out; TIMEFORMAT="process wall %R s"
  time (timeout 60 "$B" run /tmp/sweep.toml --out /tmp/sweep-out "$@" 2>&1 | grep -E "note: --backend|sweep:|rror")
  phases /tmp/sweep-out
}
{
echo "### whole run against the kernel (each twice: the first probes and compiles)"
for steps in 1000 10000; do for k in 1 2; do echo "## t=$(el)s sweep 1e7 x $steps f32 gpu ($k)"; sweep $steps f32 --backend gpu; done; done
echo "## t=$(el)s four chunks"; sweep 1000 f32 --backend gpu --chunk-trajectories 2500000
echo "## t=$(el)s auto"; sweep 1000 f32 --backend auto
echo "## t=$(el)s cpu, every core"; sweep 1000 f32 --backend cpu
echo "### whole-run column"; bn --precision f32 --steps 1000 --repeats 3
echo "### tuned from a fresh cache, probe logged"; REEB_GPU_PROBE_LOG=1 bn --precision f32,f64 --steps 10000 --repeats 3
timeout 60 "$B" info 2>&1 | grep -A3 "GPU tuning"
echo "### from the cache"; bn --precision f32,f64 --steps 10000 --repeats 3
for b in 1 8; do echo "### block $b"; REEB_GPU_FINITE_BLOCK=$b bn --precision f32,f64 --steps 10000 --repeats 3; done
# Each chaos indicator against its plain run on a hardware GPU (README, "Chaos indicators"; lavapipe's numbers are there).
echo "### indicators' cost"; timeout 120 "$B" bench --indicators --backend gpu --repeats 3 --json "$OUT/indicators.jsonl"
# SALI and GALI_2 against the plain run of the same scene on a hardware GPU
# (10^6 van der Pol orbits x 10^4 S2 steps, f32, integration seconds).
for extra in "" "sali = true" "gali = { k = 2 }"; do
  printf 'name = "align"\nmodel = "van_der_pol"\n[params]\nepsilon = { linspace = [0.5, 2.0, 1000] }\n[initial]\nq = { linspace = [0.5, 2.5, 1000] }\n[integrator]\nscheme = "s2"\ndt = 0.01\nsteps = 10000\n[output]\nfinal = ["q"]\n%s\n[run]\nprecision = "f32"\n' "$extra" > /tmp/align.toml
  echo "### alignment: ${extra:-plain}"; timeout 60 "$B" run /tmp/align.toml --backend gpu --out /tmp/align 2>&1 | tail -1; phases /tmp/align
done
} 2>&1 | tee "$OUT/reeb.txt"
wait $NV; cat /tmp/nvcc.txt
for p in f32 f64; do timeout 30 /tmp/vdp_cuda --precision $p --n 10000000 --steps 10000 --repeat 5; done 2>&1 | tee "$OUT/peers.jsonl"
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R "$B" doctor --out "$OUT/reeb-doctor.json" 2>&1 | tee "$OUT/doctor.txt"; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
