#!/bin/bash
# Issue 35 point 6, second H200 call: the finite test as one sum, hardware exp2, then doctor on the kernel to commit.
T0=$(date +%s); el() { echo $(( $(date +%s) - T0 )); }
DEADLINE=${DEADLINE:-420}
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig >/dev/null
B=$PWD/.dev/reeb-gpu; export XDG_CACHE_HOME=/tmp/cache
bn() { echo "## t=$(el)s $*"; timeout 60 $B bench --backend gpu --scenario van_der_pol/s2 --n 10000000 --precision f32,f64 "$@" 2>&1 | grep -E "gpu:|rror"; }
{
echo "### committed kernel (steps 1000, lengthened)"; bn --steps 1000
for x in "" oldfin nofin hw2 "hw2,nofin" "exp,nofin"; do echo "### REEB_X=$x"; REEB_X=$x bn --steps 10000 --repeats 3; done
echo "### committed kernel again (steps 1000)"; bn --steps 1000
} 2>&1 | tee $OUT/reeb.txt
R=$(( DEADLINE - $(el) )); echo "== t=$(el) doctor (timeout $R s)"
timeout $R $B doctor --out $OUT/reeb-doctor.json 2>&1 | tee $OUT/doctor.txt; echo "doctor rc ${PIPESTATUS[0]}"
echo "== t=$(el) end"
