//! Attractors and their basins (`output.attractors`): symmetric systems
//! give symmetric fractions, the backends and precisions the same labels,
//! a stroboscopic section the resonances' capture, shards and Zarr the same
//! labels as one run, a parameter axis continued labels; bad settings are
//! refused at their line.

use std::path::{Path, PathBuf};

use crate::common::runs::{ok, reeb, s, summary, tmp};
use crate::common::{self, npy_f64, npy_ints};

/// The unforced damped double well −q²/2 + q⁴/4 over a grid symmetric
/// under (q, p) → (−q, −p), which swaps its two wells.
const DOUBLE_WELL: &str = r#"
model = "mechanical"
[formula]
potential = "-q^2/2 + q^4/4"
damping = "0.25"
[initial]
q = { linspace = [-2.0, 2.0, 60] }
p = { linspace = [-2.0, 2.0, 60] }
[integrator]
scheme = "s2"
dt = 0.05
steps = 4000
[output]
final = ["q", "p"]
attractors = true
"#;

/// The magnetic pendulum: three magnets at radius 1 (120° apart), linear
/// damping, starts on a grid over the square [−2, 2]²; those outside the
/// disc of radius 2 stop after their first step (escapes), so that the rest
/// fill a disc, which the magnets' symmetry maps to itself. (Random starts
/// on both axes would be a product of two random lists: correlated points,
/// whose fractions scatter well beyond a binomial error.)
const MAGNETS: &str = r#"
model = "mechanical"
[formula]
dof = 2
potential = "omega^2*(q1^2 + q2^2)/2 - (1/sqrt((q1 - 1)^2 + q2^2 + d^2) + 1/sqrt((q1 + 0.5)^2 + (q2 - 0.8660254037844386)^2 + d^2) + 1/sqrt((q1 + 0.5)^2 + (q2 + 0.8660254037844386)^2 + d^2))"
damping = "alpha"
[params]
omega = 0.5
d = 0.3
alpha = 0.2
[initial]
q1 = { linspace = [-2.0, 2.0, 240] }
q2 = { linspace = [-2.0, 2.0, 240] }
p1 = 0.0
p2 = 0.0
[integrator]
scheme = "s2"
dt = 0.02
t_end = 100.0
[output]
final = ["q", "p"]
stop = "q1^2 + q2^2 - 4 > 1000*(t - 0.02)"
attractors = { every = 100 }
"#;

/// The forced double well across its forcing frequency, sampled on its
/// stroboscopic section: fixed points, cycles and a chaotic band.
const FORCED: &str = r#"
model = "mechanical"
[formula]
potential = "-q^2/2 + q^4/4 - 0.3*q*cos(omega*t)"
damping = "0.25"
forcing_frequency = "omega"
[params]
omega = { linspace = [0.6, 1.6, 11] }
[initial]
q = { linspace = [-2.0, 2.0, 24] }
p = { linspace = [-2.0, 2.0, 24] }
[integrator]
scheme = "s2"
dt = 0.05
t_end = 300.0
[output]
final = ["q", "p"]
poincare = { period = "forcing", vars = ["q", "p"], max_points = 1 }
attractors = true
"#;

/// Mercury-like tidal despinning (e = 0.2056) over (q₀, p₀), sampled once
/// an orbit on the stroboscopic section, the spin angle modulo 2π; the
/// mean spin rate classified by `resonance` in the same run.
const SPIN_ORBIT: &str = r#"
model = "spin_orbit"
[params]
eccentricity = 0.2056
epsilon = 0.05
tidal_k = 1e-2
tidal_eta = 1.0
[initial]
q = { linspace = [0.0, 3.141592653589793, 24] }
p = { linspace = [0.5, 3.5, 24] }
[integrator]
scheme = "s2"
dt = 0.3141592653589793
t_end = 10000.0
[output]
final = ["q", "p"]
poincare = { period = 6.283185307179586, vars = ["q", "p"], max_points = 2 }
average = { vars = ["p"], skip = 0.8 }
resonance = { var = "p", ratios = [[1, 1], [3, 2], [2, 1], [5, 2]], tolerance = 0.01 }
attractors = { angles = ["q"] }
[run]
precision = "f64"
"#;

/// Runs `text` (written as `dir/scene.toml`) with `args` into `dir/<out>`.
fn run(dir: &Path, text: &str, out: &str, args: &[&str]) -> PathBuf {
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, text).unwrap();
    let out = dir.join(out);
    ok(&[&["run", s(&scene), "--out", s(&out)], args].concat());
    out
}

fn labels(out: &Path) -> Vec<i32> {
    npy_ints(&out.join("attractor.npy"))
}

/// `summary.json`'s fraction and error of each label (escape: −1).
fn fractions(out: &Path) -> Vec<(i64, String, f64, f64)> {
    let s = summary(out);
    let list = s["attractors"]["fractions"].as_array().unwrap().clone();
    list.iter()
        .map(|f| {
            (
                f["label"].as_i64().unwrap(),
                f["kind"].as_str().unwrap().to_string(),
                f["fraction"].as_f64().unwrap(),
                f["fraction_error"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// The share of orbits whose labels agree once each label of `a` is
/// matched with the label of `b` most of its orbits carry.
fn agreement(a: &[i32], b: &[i32]) -> f64 {
    use std::collections::HashMap;
    let mut pairs: HashMap<(i32, i32), usize> = HashMap::new();
    for (x, y) in a.iter().zip(b) {
        *pairs.entry((*x, *y)).or_default() += 1;
    }
    let mut best: HashMap<i32, (i32, usize)> = HashMap::new();
    for (&(x, y), &c) in &pairs {
        let e = best.entry(x).or_insert((y, 0));
        if c > e.1 {
            *e = (y, c);
        }
    }
    let same = a.iter().zip(b).filter(|(x, y)| best[x].0 == **y).count();
    same as f64 / a.len() as f64
}

#[test]
fn the_double_well_splits_its_grid_in_half_between_its_two_wells() {
    let dir = tmp("attractors", "double-well");
    let out = run(&dir, DOUBLE_WELL, "f64", &["--precision", "f64"]);
    let f = fractions(&out);
    assert_eq!(f.len(), 2, "{f:?}");
    for (_, kind, fraction, error) in &f {
        assert_eq!(kind, "fixed_point");
        assert!((fraction - 0.5).abs() <= 2.0 * error, "{f:?}");
    }
    // The wells at q = ±1, p = 0, found in every orbit's last samples.
    let table: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("attractors.json")).unwrap())
            .unwrap();
    let mut wells: Vec<f64> = (0..2)
        .map(|k| table[k]["points"]["q"][0].as_f64().unwrap())
        .collect();
    wells.sort_by(f64::total_cmp);
    assert!(
        (wells[0] + 1.0).abs() < 1e-3 && (wells[1] - 1.0).abs() < 1e-3,
        "{wells:?}"
    );
    // The symmetry maps each orbit to one in the other basin.
    let l = labels(&out);
    let n = l.len();
    let swapped = (0..n).filter(|&i| l[i] != l[n - 1 - i]).count();
    assert!(swapped as f64 >= 0.99 * n as f64, "{swapped} of {n}");
    // f32 gives the same labels, but on the basins' boundaries.
    let f32 = run(&dir, DOUBLE_WELL, "f32", &["--precision", "f32"]);
    let same = agreement(&labels(&f32), &l);
    assert!(same >= 0.99, "f32 and f64 labels agree on {same}");
    let periods: Vec<i32> = npy_ints(&out.join("attractor_period.npy"));
    assert!(periods.iter().all(|&p| p == 1));
    let transient: Vec<i32> = npy_ints(&out.join("transient.npy"));
    assert!(transient.iter().all(|&t| t >= 0), "every orbit settled");
}

#[test]
fn three_symmetric_magnets_share_a_disc_of_starts_in_thirds() {
    let dir = tmp("attractors", "magnets");
    let out = run(&dir, MAGNETS, "cpu", &["--backend", "cpu"]);
    let f = fractions(&out);
    let magnets: Vec<_> = f.iter().filter(|x| x.0 >= 0).collect();
    assert_eq!(magnets.len(), 3, "{f:?}");
    // Among the orbits that started on the disc (the escapes are the rest).
    let inside: f64 = magnets.iter().map(|m| m.2).sum();
    let n = labels(&out).len() as f64 * inside;
    for (_, kind, fraction, _) in &magnets {
        assert_eq!(kind, "fixed_point");
        let share = fraction / inside;
        let error = (share * (1.0 - share) / n).sqrt();
        assert!(
            (share - 1.0 / 3.0).abs() <= 3.0 * error,
            "{share} of the disc (error {error}): {f:?}"
        );
    }
    let escaped = f.iter().find(|x| x.0 < 0).unwrap();
    // 1 − π/4 of the square lies outside the disc.
    assert!(
        (escaped.2 - (1.0 - std::f64::consts::FRAC_PI_4)).abs() < 0.01,
        "{escaped:?}"
    );
    if common::gpu().is_some() {
        let gpu = run(&dir, MAGNETS, "gpu", &["--backend", "gpu"]);
        let same = agreement(&labels(&gpu), &labels(&out));
        assert!(same >= 0.99, "CPU and GPU labels agree on {same}");
    }
}

#[test]
fn a_forced_oscillator_is_continued_along_its_frequency_on_both_backends() {
    let dir = tmp("attractors", "forced");
    let out = run(&dir, FORCED, "cpu", &["--backend", "cpu"]);
    let s = summary(&out);
    let c = &s["attractors"]["continuation"];
    assert_eq!(c["axis"], "omega");
    let values = c["values"].as_array().unwrap().len();
    assert_eq!(values, 11);
    // At each frequency the continued labels' fractions add up to one.
    let fractions = c["fractions"].as_object().unwrap();
    for v in 0..values {
        let total: f64 = fractions.values().map(|f| f[v].as_f64().unwrap()).sum();
        assert!((total - 1.0).abs() < 1e-12, "{total} at value {v}");
    }
    // Both wells' fixed points at the lowest frequency, an aperiodic band
    // in the middle.
    let table: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("attractors.json")).unwrap())
            .unwrap();
    let kinds: Vec<&str> = (table.as_array().unwrap().iter())
        .map(|a| a["kind"].as_str().unwrap())
        .collect();
    assert!(
        kinds.contains(&"aperiodic") && kinds.contains(&"fixed_point"),
        "{kinds:?}"
    );
    let low = (table.as_array().unwrap().iter())
        .filter(|a| a["found_from"].as_f64() == Some(0.6) && a["kind"] == "fixed_point")
        .count();
    assert!(low >= 2, "{table}");
    assert!(out.join("basin_fractions.png").is_file());
    if common::gpu().is_some() {
        let gpu = run(&dir, FORCED, "gpu", &["--backend", "gpu"]);
        let same = agreement(&labels(&gpu), &labels(&out));
        assert!(same >= 0.97, "CPU and GPU labels agree on {same}");
    }
}

#[test]
fn spin_orbit_capture_basins_agree_with_the_resonances_captured() {
    let dir = tmp("attractors", "spin-orbit");
    let out = run(&dir, SPIN_ORBIT, "run", &[]);
    let (l, r): (Vec<i32>, Vec<i32>) = (labels(&out), npy_ints(&out.join("resonance.npy")));
    // Each attractor lies in one resonance: its orbits' mean spin rates
    // agree on it (two attractors may share one: θ and θ + π of 1:1).
    assert!(agreement(&l, &r) >= 0.99, "{}", agreement(&l, &r));
    // 1:1 and 3:2 both capture; 3:2 is a cycle of period 2 on the section.
    let table: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("attractors.json")).unwrap())
            .unwrap();
    let spin = |a: &serde_json::Value| a["points"]["p"][0].as_f64().unwrap_or(f64::NAN);
    let rows = table.as_array().unwrap();
    let synchronous = rows
        .iter()
        .find(|a| a["kind"] == "fixed_point" && (spin(a) - 1.0).abs() < 0.1);
    let three_halves = rows
        .iter()
        .find(|a| a["period"] == 2 && (spin(a) - 1.5).abs() < 0.1);
    assert!(synchronous.is_some() && three_halves.is_some(), "{table}");
    // Angles are listed in [0, 2π).
    for a in rows {
        for q in a["points"]["q"].as_array().into_iter().flatten() {
            let q = q.as_f64().unwrap();
            assert!((0.0..std::f64::consts::TAU).contains(&q), "{q}");
        }
    }
}

#[test]
fn shards_merged_and_a_zarr_store_label_the_whole_ensemble_as_one_run() {
    let dir = tmp("attractors", "shards");
    let one = run(&dir, DOUBLE_WELL, "one", &["--chunk-trajectories", "700"]);
    let scene = dir.join("scene.toml");
    let merged = dir.join("merged");
    for k in 0..3 {
        let shard = format!("{k}/3");
        ok(&[
            "run",
            s(&scene),
            "--out",
            s(&merged),
            "--shard",
            &shard,
            "--chunk-trajectories",
            "700",
        ]);
    }
    ok(&["merge", s(&merged)]);
    for f in [
        "attractor.npy",
        "attractor_period.npy",
        "transient.npy",
        "attractors.json",
    ] {
        let (a, b) = (
            std::fs::read(one.join(f)).unwrap(),
            std::fs::read(merged.join(f)).unwrap(),
        );
        assert!(a == b, "{f} differs");
    }
    let zarr = run(&dir, DOUBLE_WELL, "zarr", &["--format", "zarr"]);
    let stored = reeb::output::zarr::read(&zarr, "attractor").unwrap();
    assert_eq!(stored, common::npy(&one.join("attractor.npy")).1);
    let s = summary(&zarr);
    assert_eq!(s["attractors"], summary(&one)["attractors"]);
    assert_eq!(s["dims"]["attractor"], serde_json::json!(["q", "p"]));
}

#[test]
fn the_points_of_an_orbit_are_its_last_samples() {
    // Without a section every `every` steps: a damped oscillator's samples
    // lose energy towards its fixed point, the last the final state.
    let dir = tmp("attractors", "points");
    let text = r#"
model = "damped_oscillator"
[params]
alpha = 0.5
[initial]
q = { linspace = [0.5, 1.5, 3] }
p = 0.0
[integrator]
scheme = "s2"
dt = 0.01
steps = 3000
[output]
final = ["q", "p"]
attractors = { every = 250, max_period = 3, skip = 0.0 }
[run]
precision = "f64"
"#;
    let out = run(&dir, text, "run", &[]);
    let q = npy_f64(&out.join("attractor_points_q.npy"));
    let p = npy_f64(&out.join("attractor_points_p.npy"));
    let last = npy_f64(&out.join("final_q.npy"));
    for i in 0..3 {
        assert_eq!(q[i * 3 + 2], last[i], "orbit {i}");
        let energy: Vec<f64> = (0..3)
            .map(|m| q[i * 3 + m].powi(2) + p[i * 3 + m].powi(2))
            .collect();
        assert!(energy[0] > energy[1] && energy[1] > energy[2], "{energy:?}");
    }
}

#[test]
fn bad_attractor_settings_are_refused_at_their_line() {
    let dir = tmp("attractors", "refusals");
    let base = DOUBLE_WELL.replace("attractors = true", "attractors = ATTRACTORS");
    let cases = [
        (
            "{ max_period = 0 }",
            "output.attractors.max_period: must be at least 1",
        ),
        (
            "{ max_period = 65 }",
            "output.attractors.max_period: 65 is more than 64",
        ),
        (
            "{ max_period = -2 }",
            "output.attractors.max_period: expected a non-negative integer",
        ),
        (
            "{ tolerance = 0.0 }",
            "output.attractors.tolerance: must be a finite number above 0",
        ),
        (
            "{ tolerance = -1e-3 }",
            "output.attractors.tolerance: must be a finite number above 0",
        ),
        (
            "{ tolerance = nan }",
            "output.attractors.tolerance: expected a finite number",
        ),
        (
            "{ tolerance = inf }",
            "output.attractors.tolerance: expected a finite number",
        ),
        (
            "{ skip = 1.0 }",
            "output.attractors.skip: must be in [0, 1)",
        ),
        (
            "{ skip = -0.1 }",
            "output.attractors.skip: must be in [0, 1)",
        ),
        (
            "{ every = 0 }",
            "output.attractors.every: must be at least 1",
        ),
        (
            "{ every = 5000 }",
            "output.attractors.every: 5000 is more than the 4000 steps",
        ),
        (
            "{ every = 1500 }",
            "output.attractors.every: 1500 steps between samples leave 1 samples",
        ),
        (
            "{ angles = [\"x\"] }",
            "output.attractors.angles: `x` is not sampled",
        ),
        (
            "{ period = 3 }",
            "output.attractors.period: unknown key; known keys here: max_period",
        ),
        ("3", "output.attractors: expected true or { max_period"),
    ];
    for (value, want) in cases {
        let path = dir.join("bad.toml");
        std::fs::write(&path, base.replace("ATTRACTORS", value)).unwrap();
        let o = reeb(&["check", s(&path)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{value} was taken");
        assert!(
            err.contains("bad.toml:") && err.contains(want),
            "{value}: {err}"
        );
    }
    // A section that records no state variable has nothing to sample.
    let path = dir.join("bad.toml");
    let text = FORCED.replace("vars = [\"q\", \"p\"]", "vars = [\"t\"]");
    std::fs::write(&path, text).unwrap();
    let err = String::from_utf8_lossy(&reeb(&["check", s(&path)]).stderr).into_owned();
    assert!(
        err.contains("output.attractors: the section records no state variable"),
        "{err}"
    );
}
