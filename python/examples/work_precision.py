"""Work against precision for the damped oscillator: every scheme's error
against its run time, f32 and f64, from reeb's work–precision report
(scenes/damped_oscillator_work_precision.toml).

    python work_precision.py [--preview] [--out work_precision.png]
"""

import argparse
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import reeb

SCENES = Path(__file__).resolve().parents[2] / "scenes"

args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
args.add_argument("--preview", action="store_true", help="the CPU only, in f64")
args.add_argument("--out", default="work_precision.png")
a = args.parse_args()

where = Path(tempfile.mkdtemp()) / "report"
options = dict(backend="cpu", precision="f64") if a.preview else {}
report = reeb.report.work_precision(SCENES / "damped_oscillator_work_precision.toml", out=where, **options)
table = report.table
print(table.groupby(["scheme", "backend", "precision"]).error_max.min())
# One backend and precision per picture (the report draws each of them).
cpu64 = table[(table.backend == "cpu") & (table.precision == "f64")]
fig, ax = plt.subplots(figsize=(7, 5))
for scheme, rows in cpu64.groupby("scheme", sort=False):
    rows = rows.sort_values("seconds")
    ax.loglog(rows.seconds, rows.error_max, "o-", ms=3, label=scheme)
ax.set_xlabel("run time (s)")
ax.set_ylabel("max error")
ax.set_title("damped oscillator, CPU f64: error against run time")
ax.legend(fontsize=7, ncol=2)
fig.savefig(a.out, dpi=120, bbox_inches="tight")
print(f"wrote {a.out}; the report's own pictures: {[p.name for p in report.pictures]}")
