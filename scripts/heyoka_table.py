"""Summarises the JSON lines of scripts/compare_heyoka.sh: per model, each of
heyoka's measurements beside reeb's fastest configuration at an error no
larger than heyoka's (and the speed ratio), then the fastest of each tool at
fixed error levels; with --png, the work–precision diagram (error against
seconds, every reeb scheme a line over its steps, heyoka a line over its
tolerances), one panel per model.

    python heyoka_table.py RESULTS.jsonl [--png OUT.png] [--cpu "CPU model, ISA"]"""
import argparse, json, re
from collections import defaultdict

ap = argparse.ArgumentParser()
ap.add_argument("results")
ap.add_argument("--png")
ap.add_argument("--cpu", default="")
a = ap.parse_args()

rows = [json.loads(l) for l in open(a.results) if l.startswith("{")]
rows = [r for r in rows if isinstance(r.get("error"), float) and "seconds" in r]
models = list(dict.fromkeys(r["model"] for r in rows))
LEVELS = [1e-2, 1e-6, 4e-10, 5e-13]


def fastest(rs, bound):
    ok = [r for r in rs if r["error"] <= bound]
    return min(ok, key=lambda r: r["seconds"]) if ok else None


def cell(r):
    return f"{r['config']}: {r['error']:.1e} in {r['seconds']:.3f} s" if r else "—"


for m in models:
    reeb = [r for r in rows if r["model"] == m and r["impl"] == "reeb"]
    hey = [r for r in rows if r["model"] == m and r["impl"] == "heyoka"]
    print(f"\n### {m}: at heyoka's error, reeb's fastest configuration as accurate\n")
    print("| heyoka | its error | seconds | reeb (fastest with error ≤ heyoka's) | seconds | reeb faster by |")
    print("|---|---|---|---|---|---|")
    for h in sorted(hey, key=lambda r: -r["error"]):
        r = fastest(reeb, h["error"])
        ratio = f"{h['seconds'] / r['seconds']:.2f}×" if r else "—"
        rcell = f"{r['config']} ({r['error']:.1e})" if r else "—"
        rsec = f"{r['seconds']:.3f}" if r else "—"
        print(f"| {h['config']} | {h['error']:.1e} | {h['seconds']:.3f} | {rcell} | {rsec} | {ratio} |")
    print(f"\n### {m}: the fastest of each at fixed error levels\n")
    print("| error ≤ | reeb | heyoka |\n|---|---|---|")
    for lv in LEVELS:
        print(f"| {lv:.0e} | {cell(fastest(reeb, lv))} | {cell(fastest(hey, lv))} |")

if a.png:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    fig, axes = plt.subplots(1, len(models), figsize=(5.2 * len(models), 4.6), squeeze=False)
    for ax, m in zip(axes[0], models):
        lines = defaultdict(list)
        for r in rows:
            if r["model"] != m:
                continue
            key = "heyoka (tolerances)" if r["impl"] == "heyoka" else re.split(r",", r["config"])[0]
            lines[key].append((r["seconds"], r["error"]))
        for key, pts in lines.items():
            pts.sort(key=lambda p: -p[1])  # along the ladder: steps or tolerances
            style = dict(color="black", lw=2.2, marker="s") if key.startswith("heyoka") else dict(marker="o", lw=1.2)
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], label=key, **style)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_title(m.replace("_", " "))
        ax.set_xlabel("seconds (integration)")
        ax.set_ylabel("max error at t_end")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"reeb's schemes (f64, CPU) against heyoka (Taylor, batch 64){' — ' + a.cpu if a.cpu else ''}", fontsize=10)
    fig.tight_layout()
    fig.savefig(a.png, dpi=110)
    print(f"\nwrote {a.png}")
