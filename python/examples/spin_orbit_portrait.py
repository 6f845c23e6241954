"""A spin–orbit Poincaré portrait from 100,489 orbits (e = 0.06, ε = 0.045;
scenes/spin_orbit_dense.toml): one point per orbital period, coloured by the
orbit's initial p.

    python spin_orbit_portrait.py [--preview] [--out spin_orbit_portrait.png]
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import reeb

SCENES = Path(__file__).resolve().parents[2] / "scenes"

args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
args.add_argument("--preview", action="store_true", help="4 values per axis, 2000 steps")
args.add_argument("--out", default="spin_orbit_portrait.png")
a = args.parse_args()

ds = reeb.run(SCENES / "spin_orbit_dense.toml", preview=a.preview)
print(ds)
q = np.mod(ds.poincare_q.values, 2 * np.pi).ravel()
p = ds.poincare_p.values.ravel()
colour = np.broadcast_to(ds.p.values[None, :, None], ds.poincare_p.shape).ravel()
keep = np.isfinite(q) & np.isfinite(p)
fig, ax = plt.subplots(figsize=(7, 5))
ax.scatter(q[keep], p[keep], c=colour[keep], s=0.05, cmap="twilight", linewidths=0)
ax.set_xlim(0, 2 * np.pi)
ax.set_xlabel("q (mod 2π)")
ax.set_ylabel("p")
ax.set_title(f"spin–orbit: {ds.sizes['q'] * ds.sizes['p']:,} orbits, {int(keep.sum()):,} points")
fig.savefig(a.out, dpi=110, bbox_inches="tight")
print(f"wrote {a.out}")
