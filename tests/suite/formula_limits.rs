//! Deep or long formulas must not crash reeb (issue 31, point 3): nesting
//! past the parser's limit is refused with the scene's error at its column,
//! and every pass from the text to the step's program (parsing, the DAG,
//! derivatives, substitution, the rewrites, lowering, the interpreter) takes
//! formulas of any length without recursion on their depth. The library
//! tests run on a 2 MiB thread stack, as small as rayon's and the test
//! harness's; the CLI tests on the main thread's 8 MiB.

use std::path::Path;
use std::process::Command;

use reeb::backend::cpu;
use reeb::scene::Scene;

/// The stack of rayon's worker threads and of the test harness's.
const SMALL_STACK: usize = 2 << 20;

fn on_small_stack<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    std::thread::Builder::new()
        .stack_size(SMALL_STACK)
        .spawn(f)
        .expect("a thread")
        .join()
        .unwrap_or_else(|e| std::panic::resume_unwind(e))
}

/// A one-degree-of-freedom scene with `potential`; the formula is line 4.
fn scene(potential: &str) -> String {
    format!(
        "name = \"deep\"\nmodel = \"mechanical\"\n[formula]\npotential = \"{potential}\"\n\
         [initial]\nq = [0.3, -0.7]\np = 0.2\n[integrator]\nscheme = \"s2\"\ndt = 0.01\n\
         steps = 20\n[output]\nfinal = [\"q\", \"p\", \"s\"]\n"
    )
}

/// The scene's error, or "accepted".
fn refusal(potential: &str) -> String {
    match Scene::parse(Path::new("deep.toml"), &scene(potential)) {
        Ok(_) => "accepted".into(),
        Err(e) => e.to_string(),
    }
}

/// The final q, p, s of the scene's two trajectories, integrated in f64 on
/// the CPU (the composed step: every rewrite and the interpreter).
fn finals(potential: &str) -> Vec<f64> {
    let s =
        Scene::parse(Path::new("deep.toml"), &scene(potential)).unwrap_or_else(|e| panic!("{e}"));
    let mut subs = s.sub_runs().expect("plans");
    let o = cpu::run::<f64>(&subs.remove(0).plan, None);
    assert_eq!(o.nonfinite_step, [0, 0], "every trajectory finite");
    o.final_values.iter().flat_map(|(_, v)| v.clone()).collect()
}

fn assert_close(got: &[f64], want: &[f64], tol: f64) {
    for (g, w) in got.iter().zip(want) {
        assert!(
            (g - w).abs() <= tol * w.abs().max(1.0),
            "{got:?} vs {want:?}"
        );
    }
}

#[test]
fn ten_thousand_parentheses_are_refused_at_their_column() {
    let e = on_small_stack(|| refusal(&format!("{}q^2{}", "(".repeat(10_000), ")".repeat(10_000))));
    assert!(
        e.starts_with("deep.toml:4: formula.potential: column 257: parentheses and function calls nested deeper than 256"),
        "{e}"
    );
    // The formula is shown around the column, not all 20 000 characters.
    let lines: Vec<&str> = e.lines().collect();
    assert_eq!(lines.len(), 3, "{e}");
    assert!(
        lines[1].starts_with("    …(((") && lines[1].ends_with("(…"),
        "{e}"
    );
    assert_eq!(lines[2].find('^'), Some(4 + 1 + 256 - 220), "{e}");
}

#[test]
fn ten_thousand_nested_sines_are_refused_at_their_column() {
    let e =
        on_small_stack(|| refusal(&format!("{}q{}", "sin(".repeat(10_000), ")".repeat(10_000))));
    assert!(
        e.starts_with("deep.toml:4: formula.potential: column 1025: parentheses and function calls nested deeper than 256"),
        "{e}"
    );
}

#[test]
fn nesting_up_to_the_limit_works() {
    let got = on_small_stack(|| finals(&format!("{}q^2/2{}", "(".repeat(256), ")".repeat(256))));
    assert_eq!(got, finals("q^2/2"));
    // A polynomial in Horner form nested 255 deep: 1 + q(1 + q(1 + …)).
    let horner = format!(
        "q^2/2 + 1e-3*q^3*{}1{}",
        "(1 + q*".repeat(255),
        ")".repeat(255)
    );
    let got = on_small_stack(move || finals(&horner));
    assert!(got.iter().all(|x| x.is_finite()), "{got:?}");
}

#[test]
fn a_hundred_thousand_minus_signs_work() {
    let got = on_small_stack(|| finals(&format!("{}q^2/2", "-".repeat(100_000))));
    assert_eq!(got, finals("q^2/2"), "an even number of signs is none");
    let got = on_small_stack(|| finals(&format!("{}q^2/2", "-".repeat(100_001))));
    assert_eq!(got, finals("-q^2/2"));
}

#[test]
fn a_sum_of_fifty_thousand_terms_works() {
    // Σ q²/10⁵ over 5·10⁴ terms = q²/2, up to rounding.
    let got = on_small_stack(|| finals(&vec!["q^2/100000"; 50_000].join(" + ")));
    assert_close(&got, &finals("q^2/2"), 1e-9);
    // Distinct terms: nothing merges, every pass sees 5·10⁴ nodes.
    let distinct: Vec<String> = (0..50_000)
        .map(|k| format!("{:e}*sin(q + {k})", 1e-5 / (1.0 + k as f64)))
        .collect();
    let got = on_small_stack(move || finals(&distinct.join(" + ")));
    assert!(got.iter().all(|x| x.is_finite()), "{got:?}");
}

#[test]
fn a_one_megabyte_sum_works() {
    let n = 76_925;
    let text = vec!["q^2/181818"; n].join(" + ");
    assert!(text.len() > 1_000_000);
    let got = on_small_stack(move || finals(&text));
    // n terms of q²/181 818: V ≈ 0.423 q².
    let want = finals(&format!("{}*q^2", n as f64 / 181_818.0));
    assert_close(&got, &want, 1e-9);
}

#[test]
fn a_tower_of_five_thousand_powers_works() {
    // q^q^…^q: every level differentiates into the next (a chain 5000 deep).
    let tower = vec!["q"; 5_000].join("^");
    let got = on_small_stack(move || {
        let s =
            Scene::parse(Path::new("deep.toml"), &scene(&tower)).unwrap_or_else(|e| panic!("{e}"));
        let plan = s.sub_runs().expect("plans").remove(0).plan;
        cpu::run::<f64>(&plan, None).final_values
    });
    assert_eq!(got.len(), 3);
}

#[test]
fn a_column_after_wide_characters_is_not_cut_inside_one() {
    // The parser counts characters; `α` is two bytes.
    let e = refusal("αα $ q");
    assert!(e.contains("column 4: unexpected `$`"), "{e}");
    assert!(e.ends_with("\n    αα $ q\n       ^"), "{e}");
}

/// `reeb check` on a scene file: exit code and output.
fn check(name: &str, potential: &str) -> (Option<i32>, String) {
    let dir = std::env::temp_dir().join(format!("reeb-formula-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, scene(potential)).expect("a scene file");
    let out = Command::new(env!("CARGO_BIN_EXE_reeb"))
        .arg("check")
        .arg(&path)
        .output()
        .expect("reeb runs");
    let _ = std::fs::remove_file(&path);
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code(), text)
}

#[test]
fn the_command_line_refuses_or_takes_them_without_aborting() {
    let (code, out) = check(
        "parens",
        &format!("{}q{}", "(".repeat(10_000), ")".repeat(10_000)),
    );
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("parens.toml:4: formula.potential: column 257: parentheses and function calls nested deeper than 256"), "{out}");
    for (name, potential) in [
        ("minus", format!("{}q", "-".repeat(100_000))),
        ("sum", vec!["q^2/100000"; 50_000].join(" + ")),
    ] {
        let (code, out) = check(name, &potential);
        assert_eq!(code, Some(0), "{name}: {out}");
    }
    // A tower of powers is taken, and refused only because q^q^… of the
    // scene's negative q is not a real number where the trajectory starts.
    let (code, out) = check("tower", &vec!["q"; 5_000].join("^"));
    assert_eq!(code, Some(1), "tower: {out}");
    assert!(
        out.contains("formula.potential: V is NaN where a trajectory starts (q = -0.7"),
        "{out}"
    );
}
