"""Error against run time beside heyoka for the two models that
../shared/peers/wp_heyoka.py (van der Pol) does not cover: the dissipative
spin–orbit problem (time-dependent: heyoka with hy.time) and perturbed Kepler.
The same method as that script: one f64 ensemble, error = max over the
ensemble of |q(T) − q_ref(T)| with q_ref from heyoka at tol 1e-15; time =
reeb's `integration_seconds` (CPU backend, every thread) and heyoka's
`ensemble_propagate_until_batch` wall time (batch 64; the JIT build is not
counted).

    python wp_heyoka_models.py REEB --model spin_orbit|kepler [--n 16384] [--t-end 50]
        [--tols 1e-6,1e-9,1e-12] [--schemes s2:0.01,kahanli8:0.1,...]

Jobs (SPEC §2.1):
  spin_orbit  θ'' = −ε pref Σ_m W_m(e) sin(2θ − m t) − K(θ' − η) + λΩ sin(Ωt) pref θ',
              pref = 1/(1 + λ cos Ωt); e = 0.01, ε = 0.0075, λ = 0.01, Ω = 1,
              K = 10⁻³, η = 1 (the resonant runs of seed 001 with tides);
              θ(0) = 0, θ'(0) = linspace(0.5, 1.5, N).
  kepler      q'' = −q/|q|³ − α sin(θt) q', α = 0.01, θ = 2π; orbits of
              semi-major axis 1 from perihelion, eccentricity linspace(0, 0.5, N).
Prints one JSON line per measurement (as wp_heyoka.py) and a table sorted by error."""
import argparse, json, os, subprocess, sys, tempfile, time
from fractions import Fraction as F
import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("reeb")
ap.add_argument("--model", choices=["spin_orbit", "kepler"], required=True)
ap.add_argument("--n", type=int, default=16384)
ap.add_argument("--t-end", type=float, default=50.0)
ap.add_argument("--batch", type=int, default=64)
ap.add_argument("--tols", default="1e-6,1e-9,1e-12")
ap.add_argument("--schemes", default="s2:0.01,kahanli6:0.05,kahanli8:0.1,kahanli8:0.05,sofspa10:0.1")
a = ap.parse_args()
import heyoka as hy

N, T = a.n, a.t_end
if N % a.batch:
    sys.exit("--n must be a multiple of --batch")

# SPEC §2.1's Cayley table: m → [(k, c)], W_m(e) = Σ c e^k.
CAYLEY = {
    -5: [(7, F(15625, 129024))], -4: [(6, F(4, 45))], -3: [(5, F(81, 1280)), (7, F(81, 2048))],
    -2: [(4, F(1, 24)), (6, F(7, 240))], -1: [(3, F(1, 48)), (5, F(11, 768)), (7, F(313, 30720))],
    1: [(1, F(-1, 2)), (3, F(1, 16)), (5, F(-5, 384)), (7, F(-143, 18432))],
    2: [(0, F(1)), (2, F(-5, 2)), (4, F(13, 16)), (6, F(-35, 288))],
    3: [(1, F(7, 2)), (3, F(-123, 16)), (5, F(489, 128)), (7, F(-1763, 2048))],
    4: [(2, F(17, 2)), (4, F(-115, 6)), (6, F(601, 48))],
    5: [(3, F(845, 48)), (5, F(-32525, 768)), (7, F(208225, 6144))],
    6: [(4, F(533, 16)), (6, F(-13827, 160))],
    7: [(5, F(228347, 3840)), (7, F(-3071075, 18432))],
    8: [(6, F(73369, 720))],
    9: [(7, F(12144273, 71680))],
}
SO = dict(eccentricity=0.01, epsilon=0.0075, **{"lambda": 0.01}, omega=1.0, tidal_k=1e-3, tidal_eta=1.0)
KEPLER = dict(alpha=0.01, theta=2 * np.pi)


def spin_orbit():
    """(system, initial states N × 2, reeb scene body, components of q)."""
    q, p = hy.make_vars("q", "p")
    e, eps, lam, om, k, eta = (SO[x] for x in ["eccentricity", "epsilon", "lambda", "omega", "tidal_k", "tidal_eta"])
    pref = 1.0 / (1.0 + lam * hy.cos(om * hy.time))
    forcing = sum(float(sum(c * F(e) ** kk for kk, c in terms)) * hy.sin(2.0 * q - float(m) * hy.time)
                  for m, terms in CAYLEY.items())
    f = k - lam * om * hy.sin(om * hy.time) * pref
    system = [(q, p), (p, -eps * pref * forcing + k * eta - f * p)]
    p0 = np.linspace(0.5, 1.5, N)
    init = np.stack([np.zeros(N), p0], axis=1)
    params = "\n".join(f"{key} = {val!r}" for key, val in SO.items())
    scene = f"""model = "spin_orbit"
[params]
{params}
[initial]
q = 0.0
p = {{ linspace = [0.5, 1.5, {N}] }}
"""
    return system, init, scene, [0]


def kepler():
    x, y, vx, vy = hy.make_vars("x", "y", "vx", "vy")
    r3 = (x * x + y * y) ** 1.5
    f = KEPLER["alpha"] * hy.sin(KEPLER["theta"] * hy.time)
    system = [(x, vx), (y, vy), (vx, -x / r3 - f * vx), (vy, -y / r3 - f * vy)]
    e = np.linspace(0.0, 0.5, N)
    init = np.stack([1 - e, np.zeros(N), np.zeros(N), np.sqrt((1 + e) / (1 - e))], axis=1)
    scene = f"""model = "kepler"
[params]
alpha = {KEPLER['alpha']!r}
theta = {KEPLER['theta']!r}
[initial]
eccentricity = {{ linspace = [0.0, 0.5, {N}] }}
"""
    return system, init, scene, [0, 1]


system, init, scene_head, q_cols = {"spin_orbit": spin_orbit, "kepler": kepler}[a.model]()
dim = init.shape[1]


def heyoka(tol, batch):
    ta = hy.taylor_adaptive_batch(system, np.zeros((dim, batch)), tol=tol)

    def gen(tc, i):
        tc.set_time(np.zeros(batch))
        tc.state[:] = init[i * batch:(i + 1) * batch].T
        return tc
    t0 = time.perf_counter()
    res = hy.ensemble_propagate_until_batch(ta, T, N // batch, gen)
    sec = time.perf_counter() - t0
    return np.concatenate([r[0].state[q_cols].T for r in res]), sec


ref, _ = heyoka(1e-15, a.batch)
rows = []
for tol in [float(x) for x in a.tols.split(",")]:
    fin, sec = heyoka(tol, a.batch)
    rows.append({"impl": "heyoka", "model": a.model, "config": f"tol {tol:g}, batch {a.batch}", "seconds": sec,
                 "error": float(np.max(np.abs(fin - ref)))})
    print(json.dumps(rows[-1]), flush=True)
tmp = tempfile.mkdtemp(prefix=f"wp-heyoka-{a.model}-")
for item in a.schemes.split(","):
    scheme, dt = item.split(":")
    d = f"{tmp}/{scheme}_{dt}"
    os.makedirs(d)
    open(f"{d}/s.toml", "w").write(scene_head + f"""[integrator]
scheme = "{scheme}"
dt = {dt}
t_end = {T}
[output]
final = ["q"]
[run]
precision = "f64"
""")
    p = subprocess.run([a.reeb, "run", f"{d}/s.toml", "--backend", "cpu", "--out", f"{d}/o"], capture_output=True, text=True)
    if p.returncode:
        print(json.dumps({"impl": "reeb", "model": a.model, "config": item, "error": p.stderr.strip()[-300:]}))
        continue
    sec = json.load(open(f"{d}/o/summary.json"))["integration_seconds"]
    fin = np.load(f"{d}/o/final_q.npy").reshape(N, len(q_cols))
    rows.append({"impl": "reeb", "model": a.model, "config": f"{scheme}, dt {dt}", "seconds": sec,
                 "error": float(np.max(np.abs(fin - ref)))})
    print(json.dumps(rows[-1]), flush=True)
print(f"\n{a.model}, {N} trajectories, t = {T}, f64, {os.cpu_count()} threads\n")
print("| error | seconds | implementation |\n|---|---|---|")
for r in sorted(rows, key=lambda r: -r["error"]):
    print(f"| {r['error']:.2e} | {r['seconds']:.3f} | {r['impl']}: {r['config']} |")
