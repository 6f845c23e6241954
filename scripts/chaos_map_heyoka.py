"""A chaos map, reeb against heyoka: the maximal Lyapunov exponent λ₁ over
the forced van der Pol cascade, both measured here, one table.

Job: q'' − ε(1 − q²) q' + q = A cos(ω t), A = ε = 5, ω_i = linspace(2.45,
2.47, N), (q, q')(0) = (2, 2), t in [0, T], f64. λ₁ by Benettin's method:
one deviation vector, renormalised every time unit, ln‖w‖ summed after the
first fifth of the run (reeb: `lyapunov = { every = 1/dt, skip = 0.2 }`,
its exact tangent map of the step; heyoka: the variational equations
integrated with the orbit, taylor_adaptive_batch, batch mode, a thread per
core). Accuracy: |λ₁ − λ₁_ref| against heyoka at tol 1e-15, its 90th
percentile over the regular orbits (λ₁_ref < −0.002: periodic attractors,
where a finite-time exponent converges; the largest is a few orbits near
the cascade's bifurcations, where coexisting attractors take orbits to
another one at any tolerance) and its median over the chaotic ones (where
it converges only statistically); and the orbits whose class (λ₁ above or
below 0.002) is the reference's. Time: reeb's
`integration_seconds` from summary.json (CPU backend, every thread);
heyoka's wall time of the propagation (JIT compilation not counted).

    python chaos_map_heyoka.py REEB [--n 1000] [--t-end 1500] [--batch 40]
        [--renorm 50] [--tols 1e-3,1e-6,...] [--schemes kahanli8:0.05:f32,...]

Needs heyoka (7.13.2, the peers' venv) and numpy. Prints one JSON line per
measurement, then a markdown table: for each accuracy, the fastest
configuration of each that reaches it, and the ratio.
"""
import argparse, json, os, subprocess, sys, tempfile, time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("reeb")
ap.add_argument("--n", type=int, default=1000)
ap.add_argument("--t-end", type=float, default=1500.0)
ap.add_argument("--batch", type=int, default=40, help="heyoka's batch (the fastest measured: 40)")
ap.add_argument("--threads", type=int, default=os.cpu_count())
ap.add_argument("--renorm", type=int, default=50,
                help="heyoka: time units between renormalisations (50 is 1.6x faster than 10, 6x than 1, "
                     "at the same accuracy)")
ap.add_argument("--tols", default="1e-3,1e-4,1e-6,1e-8,1e-10,1e-12")
ap.add_argument("--ref-tol", type=float, default=1e-15)
ap.add_argument("--schemes", default="s2:0.0025,triple_jump4:0.02,triple_jump4:0.01,yoshida6a:0.04,"
                                     "yoshida6a:0.02,kahanli8:0.1,kahanli8:0.05,kahanli8:0.025,"
                                     "triple_jump4:0.02:f32,kahanli6:0.05:f32,yoshida6a:0.04:f32,"
                                     "kahanli8:0.1:f32,kahanli8:0.0625:f32,kahanli8:0.05:f32",
                help="reeb's configurations, scheme:dt[:f32|f64] (default f64)")
a = ap.parse_args()
import heyoka as hy

N, T, B = a.n, a.t_end, a.batch
EPS, AMP = 5.0, 5.0
SKIP = 0.2
omega = np.linspace(2.45, 2.47, N)
if N % B:
    sys.exit("--n must be a multiple of --batch")

q, s, dq, ds = hy.make_vars("q", "s", "dq", "ds")
eps, amp, w = hy.par[0], hy.par[1], hy.par[2]
system = [
    (q, s),
    (s, eps * (1 - q ** 2) * s - q + amp * hy.cos(w * hy.time)),
    (dq, ds),
    (ds, eps * (1 - q ** 2) * ds - 2 * eps * q * s * dq - dq),
]


def heyoka_lambda(tol):
    """λ₁ of every ω, and the propagation's wall time."""
    start = np.array([[2.0] * B, [2.0] * B, [1.0] * B, [0.0] * B])
    assert int(T) % a.renorm == 0, "--renorm must divide the horizon"
    pars = np.array([[EPS] * B, [AMP] * B, [0.0] * B])
    proto = hy.taylor_adaptive_batch(system, start, tol=tol, pars=pars)

    def batch(k):
        ta = hy.taylor_adaptive_batch(system, start, tol=tol, pars=pars) if k else proto
        ta.set_time(np.zeros(B))
        ta.state[:] = start
        ta.pars[2, :] = omega[k * B:(k + 1) * B]
        total = np.zeros(B)
        first = int(np.ceil(SKIP * T))
        # ln‖w‖ at the skip time taken off the sums (a multiple of --renorm).
        first = first // a.renorm * a.renorm
        for unit in range(a.renorm, int(T) + 1, a.renorm):
            ta.propagate_until(float(unit))
            norm = np.hypot(ta.state[2], ta.state[3])
            if unit > first:
                total += np.log(norm)
            ta.state[2:] /= norm
        return total / (T - first)

    t0 = time.perf_counter()
    with ThreadPoolExecutor(a.threads) as pool:
        lam = np.concatenate(list(pool.map(batch, range(N // B))))
    return lam, time.perf_counter() - t0


SCENE = """name = "chaos_map"
model = "van_der_pol"
[params]
epsilon = {eps}
forcing_amplitude = {amp}
forcing_frequency = {{ linspace = [2.45, 2.47, {n}] }}
[initial]
q = 2.0
s = 2.0
[integrator]
scheme = "{scheme}"
dt = {dt}
t_end = {t}
[output]
final = ["q"]
lyapunov = {{ every = {every}, skip = {skip} }}
[run]
backend = "cpu"
precision = "{precision}"
"""


def reeb_lambda(scheme, dt, precision, tmp):
    every = round(1.0 / dt)
    if abs(every * dt - 1.0) > 1e-12:
        sys.exit(f"dt = {dt}: a time unit is not a whole number of steps")
    path = os.path.join(tmp, "scene.toml")
    with open(path, "w") as f:
        f.write(SCENE.format(eps=EPS, amp=AMP, n=N, scheme=scheme, dt=dt, t=T, every=every, skip=SKIP,
                             precision=precision))
    out = os.path.join(tmp, "out")
    subprocess.run([a.reeb, "run", path, "--out", out, "--force"], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "summary.json")) as f:
        sec = json.load(f)["integration_seconds"]
    return np.load(os.path.join(out, "lyapunov.npy"))[:, 0], sec


def errors(lam, ref):
    """The 90th percentile of |Δλ₁| over the regular orbits, its median over
    the chaotic ones, and the fraction of orbits classed as the reference."""
    regular = ref < -0.002
    d = np.abs(lam - ref)
    chaotic = float(np.median(d[~regular])) if (~regular).any() else 0.0
    same = float(np.mean((lam > 0.002) == (ref > 0.002)))
    return float(np.percentile(d[regular], 90)), chaotic, same


ref, ref_sec = heyoka_lambda(a.ref_tol)
regular = int(np.sum(ref < -0.002))
print(json.dumps({"reference": f"heyoka tol {a.ref_tol:g}", "seconds": ref_sec,
                  "regular": regular, "chaotic": N - regular}), flush=True)
rows = []
for tol in [float(x) for x in a.tols.split(",")]:
    lam, sec = heyoka_lambda(tol)
    reg, cha, same = errors(lam, ref)
    rows.append({"impl": "heyoka", "config": f"tol {tol:g}, batch {B}, renormalised every {a.renorm}",
                 "seconds": sec, "regular": reg,
                 "chaotic": cha, "same_class": same})
    print(json.dumps(rows[-1]), flush=True)
tmp = tempfile.mkdtemp(prefix="chaos-map-")
for item in filter(None, a.schemes.split(",")):
    scheme, dt, precision = (item.split(":") + ["f64"])[:3]
    lam, sec = reeb_lambda(scheme, float(dt), precision, tmp)
    reg, cha, same = errors(lam.astype(float), ref)
    rows.append({"impl": "reeb", "config": f"{scheme} dt {dt} {precision}", "seconds": sec, "regular": reg,
                 "chaotic": cha, "same_class": same})
    print(json.dumps(rows[-1]), flush=True)

print(f"\n{N} values of ω, t = {T:g}, λ₁ error against heyoka at tol {a.ref_tol:g} "
      f"(90th percentile over the {regular} regular orbits)\n")
print("| error of λ₁ (regular, p90) ≤ | reeb | seconds | heyoka | seconds | heyoka / reeb |")
print("|---|---|---|---|---|---|")
for target in (1e-2, 1e-3, 1e-4, 1e-5):
    best = {}
    for impl in ("reeb", "heyoka"):
        ok = [r for r in rows if r["impl"] == impl and r["regular"] <= target]
        best[impl] = min(ok, key=lambda r: r["seconds"]) if ok else None
    r, h = best["reeb"], best["heyoka"]
    cell = lambda x: (x["config"], f"{x['seconds']:.3g}") if x else ("none reaches it", "")
    ratio = f"{h['seconds'] / r['seconds']:.1f}×" if r and h else ""
    print(f"| {target:g} | {' | '.join(cell(r))} | {' | '.join(cell(h))} | {ratio} |")
