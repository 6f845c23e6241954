"""reeb.run against the `reeb` command on the same scene: 10⁶ van der Pol
trajectories × 1000 S2 steps (f32, final q and s), wall time of each, turn
about, medians and the ratio pair by pair.

    python overhead.py [--pairs 7] [--reeb target/release/reeb]
"""

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import reeb

REPO = Path(__file__).resolve().parents[2]
SCENE = """name = "overhead"
model = "van_der_pol"
[params]
epsilon = { linspace = [0.1, 3.0, 1000] }
[initial]
q = { linspace = [0.5, 2.5, 1000] }
[integrator]
scheme = "s2"
dt = 0.01
steps = 1000
[output]
final = ["q", "s"]
[run]
backend = "cpu"
precision = "f32"
"""

args = argparse.ArgumentParser()
args.add_argument("--pairs", type=int, default=7)
args.add_argument("--reeb", default=str(REPO / "target" / "release" / "reeb"))
a = args.parse_args()

work = Path(tempfile.mkdtemp())
scene = work / "overhead.toml"
scene.write_text(SCENE)
cli, py, ratio = [], [], []
for k in range(a.pairs):
    t = time.perf_counter()
    subprocess.run([a.reeb, "run", str(scene), "--out", str(work / "cli"), "--force"], check=True, capture_output=True)
    cli.append(time.perf_counter() - t)
    t = time.perf_counter()
    ds = reeb.run(scene, progress=False)
    py.append(time.perf_counter() - t)
    ratio.append(py[-1] / cli[-1])
    assert ds.final_q.shape == (1000, 1000)
print(f"reeb run (CLI): median {statistics.median(cli):.3f} s; reeb.run: median {statistics.median(py):.3f} s; "
      f"reeb.run / CLI pair by pair: median {statistics.median(ratio):.3f} (min {min(ratio):.3f}, max {max(ratio):.3f}), {a.pairs} pairs")
