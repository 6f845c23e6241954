#!/usr/bin/env bash
# Every shipped scene run by one reeb binary into a folder of outputs, or two
# such folders compared array by array (every .npy byte for byte).
#
#   scripts/dev/scene_bits.sh run REEB OUTDIR [cpu|gpu]   # runs every scene
#   scripts/dev/scene_bits.sh compare DIR_A DIR_B        # cmp of every .npy,
#                                                        # and summary.json
#
# For comparing a build of the starting commit with a new one before
# landing a change that must leave every shipped scene's arrays as they were.
set -euo pipefail
cd "$(dirname "$0")/../.."
case "${1:-}" in
  run)
    reeb="$2"; out="$3"; backend="${4:-cpu}"
    mkdir -p "$out"
    for scene in scenes/*.toml; do
      name="$(basename "$scene" .toml)"
      rm -rf "$out/$name"
      start=$(date +%s.%N)
      if "$reeb" run "$scene" --backend "$backend" --out "$out/$name" >"$out/$name.log" 2>&1; then
        printf '%-45s %6.1f s\n' "$name" "$(echo "$(date +%s.%N) - $start" | bc)"
      else
        printf '%-45s FAILED (%s)\n' "$name" "$out/$name.log"
      fi
    done
    ;;
  compare)
    a="$2"; b="$3"; bad=0; n=0
    for dir in "$a"/*/; do
      name="$(basename "$dir")"
      for f in "$dir"*.npy; do
        [ -e "$f" ] || continue
        n=$((n + 1))
        g="$b/$name/$(basename "$f")"
        if [ ! -e "$g" ]; then echo "missing: $g"; bad=$((bad + 1));
        elif ! cmp -s "$f" "$g"; then echo "differs: $name/$(basename "$f")"; bad=$((bad + 1)); fi
      done
      for g in "$b/$name/"*.npy; do
        [ -e "$g" ] && [ ! -e "$dir$(basename "$g")" ] && echo "new: $name/$(basename "$g")"
      done
    done
    echo "$n arrays compared, $bad differ or are missing"
    # summary.json but what differs from run to run (clock, speed, command)
    python3 - "$a" "$b" <<'PY' || bad=$((bad + 1))
import json, os, sys
a, b = sys.argv[1], sys.argv[2]
volatile = {"utc", "command_line", "traj_steps_per_s", "integration_clock"}
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items()
                if k not in volatile and "seconds" not in k and k != "timing"}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
bad = 0
for name in sorted(os.listdir(a)):
    pa, pb = (os.path.join(d, name, "summary.json") for d in (a, b))
    if not os.path.exists(pa):
        continue
    ja, jb = (strip(json.load(open(p))) for p in (pa, pb))
    for k in sorted(set(ja) | set(jb)):
        if ja.get(k) != jb.get(k):
            print(f"summary differs: {name}: {k}")
            bad += 1
print(f"summaries compared, {bad} keys differ")
sys.exit(bad > 0)
PY
    [ "$bad" -eq 0 ]
    ;;
  *) sed -n 2,10p "$0"; exit 2 ;;
esac
