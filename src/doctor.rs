//! `reeb doctor`: one command that checks and measures the GPU backend on the
//! machine it runs on — in the binary, since a GPU machine may have neither
//! network nor a Rust toolchain. It lists the adapters, runs `reeb verify` on
//! the GPU in f32 and f64 (where the adapter has SHADER_F64), compares the
//! GPU with the CPU on every model × a few schemes × both precisions,
//! measures both forms of the f32 exp on the adapter, and measures both
//! backends' throughput; the whole as one JSON report.

use std::time::Instant;

use serde::Serialize;

use crate::backend::gpu::accuracy::{exp_f32_accuracy, ExpAccuracy, HARDWARE_EXP_ULP};
use crate::backend::gpu::codegen::ExpForm;
use crate::backend::gpu::{is_software, list_adapters, AdapterSummary, GpuContext};
use crate::backend::{BackendChoice, Engine};
use crate::bench::{self, Row, Scenario};
use crate::models::MODEL_NAMES;
use crate::num::precision::Precision;
use crate::plan::{Plan, Problem, Source};
use crate::verify::samples::{first_var, problem};
use crate::verify::{largest_difference, run_all, Target};

/// Schemes of the agreement check: S2, a classical and an optimised
/// composition, and RK4 (a comparison method with its own kernels).
pub const AGREEMENT_SCHEMES: [&str; 4] = ["s2", "yoshida6a", "kahanli8", "rk4"];
/// CPU–GPU tolerances of the agreement check, relative to max(1, |cpu|),
/// over 60 steps: those of `tests/suite/gpu.rs`.
pub const TOLERANCE_F32: f64 = 2e-4;
pub const TOLERANCE_F64: f64 = 1e-10;
/// The f32 tolerance where the kernels' exp is the adapter's exp2 (a
/// different function from the CPU's, within 4 ULP): that of
/// `tests/suite/gpu.rs::hardware_exp_agrees_with_the_cpu`. On an H200 Kepler
/// kahanli8 differs by 2.2e-4, where the CPU's f32 is itself 1.2e-4 from
/// its f64.
pub const TOLERANCE_F32_HARDWARE_EXP: f64 = 1e-3;
/// The throughput scenarios.
pub const BENCH_SCENARIOS: [Scenario; 4] = [
    Scenario::VdpS2,
    Scenario::SpinOrbitS2,
    Scenario::VdpYoshida6a,
    Scenario::LienardFormulaS2,
];

/// What to run.
pub struct DoctorOptions {
    /// Adapter index of `reeb info`'s list (default: the one `--backend gpu` takes).
    pub adapter: Option<usize>,
    /// Ensemble sizes of the throughput rows (default: 10⁶ and 10⁷ on a
    /// hardware adapter, 10⁴ and 10⁵ on a software one or none).
    pub sizes: Option<Vec<usize>>,
    /// Skip `reeb verify` (the longest part on a software adapter).
    pub skip_verify: bool,
}

/// The report (`reeb-doctor.json`).
#[derive(Debug, Serialize)]
pub struct Report {
    pub reeb: &'static str,
    pub cpu: Cpu,
    pub adapters: Vec<AdapterSummary>,
    /// The adapter checked, as `--backend gpu` names it; `None` without one.
    pub adapter: Option<String>,
    pub software_adapter: bool,
    pub verify: Vec<VerifyRun>,
    pub agreement: Vec<Agreement>,
    /// Both forms of the f32 `exp` measured on the adapter.
    pub exp: Vec<ExpCheck>,
    pub bench: Vec<Row>,
    /// The launch `reeb tune` chooses for each scenario's model, with the
    /// GPU's and the CPU's rates the probe measured (what `auto` weighs).
    pub tuning: Vec<Tuned>,
    /// What could not be done, and why.
    pub problems: Vec<String>,
    pub seconds: f64,
}

#[derive(Debug, Serialize)]
pub struct Cpu {
    pub model: String,
    pub isa: &'static str,
    pub threads: usize,
}

/// One plan shape's tuning.
#[derive(Debug, Serialize)]
pub struct Tuned {
    pub shape: String,
    pub launch: String,
    pub gpu_rate: f64,
    pub cpu_rate: f64,
    pub probe_seconds: f64,
    pub compile_seconds: f64,
}

/// `reeb verify --backend gpu` at one precision.
#[derive(Debug, Serialize)]
pub struct VerifyRun {
    pub precision: Precision,
    pub passed: usize,
    pub failed: usize,
    /// The failed rows: name, expected, measured.
    pub failures: Vec<String>,
    pub seconds: f64,
}

/// One form of the f32 `exp` on the adapter (`gpu::accuracy`).
#[derive(Debug, Serialize)]
pub struct ExpCheck {
    #[serde(flatten)]
    pub accuracy: ExpAccuracy,
    /// The most ULPs it may be off: 2 for reeb's polynomial (as on the
    /// CPU), [`HARDWARE_EXP_ULP`] for the adapter's exp2.
    pub bound: f64,
    pub pass: bool,
    /// Is it the form the checked device's kernels use?
    pub in_use: bool,
}

/// The largest CPU–GPU difference of one model × scheme × precision.
#[derive(Debug, Serialize)]
pub struct Agreement {
    pub model: String,
    pub scheme: String,
    pub precision: Precision,
    /// max |gpu − cpu| / max(1, |cpu|) over the final values: infinite
    /// where one is finite and the other not, NaN where a run failed
    /// (both `null` in the JSON).
    pub worst: f64,
    pub tolerance: f64,
    pub pass: bool,
    pub error: Option<String>,
}

/// Runs every part, calling `progress` with a line as each begins.
pub fn run(opts: &DoctorOptions, mut progress: impl FnMut(&str)) -> Report {
    let start = Instant::now();
    let mut problems = vec![];
    let adapters = list_adapters();
    let mut engine = match Engine::gpu(opts.adapter) {
        Ok(e) => Some(e),
        Err(e) => {
            problems.push(format!("no GPU backend: {e}"));
            None
        }
    };
    let ctx = match &engine {
        Some(Engine::Gpu(c)) => Some(c),
        _ => None,
    };
    let software = ctx.is_none_or(|c| is_software(&c.info));
    let adapter = ctx.map(|c| c.describe());
    let f64_ok = engine.as_ref().is_some_and(|e| e.runs(Precision::F64));
    if engine.is_some() && !f64_ok {
        problems.push("the adapter has no SHADER_F64: f64 is checked on the CPU only".into());
    }
    let precisions: Vec<Precision> = [Precision::F32, Precision::F64]
        .into_iter()
        .filter(|p| *p == Precision::F32 || f64_ok)
        .collect();
    let mut verify = vec![];
    if !opts.skip_verify {
        for &p in &precisions {
            let Some(e) = engine.take() else { break };
            progress(&format!("verify on the GPU, {p}"));
            let (run, e) = verify_on(e, p);
            verify.push(run);
            engine = Some(e);
        }
    }
    let mut agreement = vec![];
    if let Some(e) = &engine {
        progress("CPU–GPU agreement: every model × s2, yoshida6a, kahanli8, rk4");
        for &p in &precisions {
            agreement.extend(agree(e, p));
        }
    }
    let sizes = opts.sizes.clone().unwrap_or(if software {
        vec![10_000, 100_000]
    } else {
        vec![1_000_000, 10_000_000]
    });
    let exp = match ctx_of(engine.as_ref()) {
        Some(c) => {
            progress("f32 exp on the adapter: reeb's polynomial and the adapter's exp2");
            exp_checks(c, &mut problems)
        }
        None => vec![],
    };
    let tuning = tune(engine.as_ref(), &precisions, &mut progress, &mut problems);
    let bench = throughput(engine.as_ref(), &sizes, &mut progress, &mut problems);
    Report {
        reeb: env!("CARGO_PKG_VERSION"),
        cpu: cpu(),
        adapters,
        adapter,
        software_adapter: software,
        verify,
        agreement,
        exp,
        bench,
        tuning,
        problems,
        seconds: start.elapsed().as_secs_f64(),
    }
}

fn ctx_of(engine: Option<&Engine>) -> Option<&GpuContext> {
    match engine {
        Some(Engine::Gpu(c)) => Some(c),
        _ => None,
    }
}

/// Both forms of the f32 `exp` over 2²⁰ arguments.
fn exp_checks(ctx: &GpuContext, problems: &mut Vec<String>) -> Vec<ExpCheck> {
    let mut rows = vec![];
    for (form, bound) in [(ExpForm::Exact, 2.0), (ExpForm::Hardware, HARDWARE_EXP_ULP)] {
        match exp_f32_accuracy(ctx, form, 1 << 20) {
            Ok(accuracy) => rows.push(ExpCheck {
                pass: accuracy.max_ulp <= bound,
                in_use: ctx.exp_f32 == form,
                accuracy,
                bound,
            }),
            Err(e) => problems.push(format!(
                "the {} f32 exp could not be measured: {e}",
                form.name()
            )),
        }
    }
    rows
}

/// The GPU launch of each scenario's model, probed again (and cached).
fn tune(
    engine: Option<&Engine>,
    precisions: &[Precision],
    progress: &mut impl FnMut(&str),
    problems: &mut Vec<String>,
) -> Vec<Tuned> {
    let Some(engine) = engine else {
        return vec![];
    };
    progress("tuning the launch of each scenario's model (about 1 s each)");
    let rows = crate::bench::tune(engine, None, precisions, |_| {});
    match rows {
        Ok(rows) => rows
            .into_iter()
            .map(|t| Tuned {
                shape: t.shape,
                launch: t.tuned.launch.describe(),
                gpu_rate: t.tuned.gpu_rate,
                cpu_rate: t.tuned.cpu_rate,
                probe_seconds: t.tuned.probe_seconds,
                compile_seconds: t.tuned.compile_seconds,
            })
            .collect(),
        Err(e) => {
            problems.push(format!("tuning failed: {e}"));
            vec![]
        }
    }
}

fn cpu() -> Cpu {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    Cpu {
        model,
        isa: crate::backend::cpu::isa().label(),
        threads: crate::backend::cpu::threads(),
    }
}

/// `reeb verify` on `engine` at `precision`; gives the engine back.
fn verify_on(engine: Engine, precision: Precision) -> (VerifyRun, Engine) {
    let t = Instant::now();
    let target = Target { engine, precision };
    let rows = run_all(&target, |_| {});
    let failures: Vec<String> = rows
        .iter()
        .filter(|c| !c.pass)
        .map(|c| {
            format!(
                "{}: expected {}, measured {}",
                c.name, c.expected, c.measured
            )
        })
        .collect();
    let run = VerifyRun {
        precision,
        passed: rows.len() - failures.len(),
        failed: failures.len(),
        failures,
        seconds: t.elapsed().as_secs_f64(),
    };
    (run, target.engine)
}

/// A sample ensemble of `model`: 16 initial values of its first variable
/// (±5 %), 60 steps of 0.05, every integrated variable's final value.
fn ensemble(model: &str, scheme: &str) -> Option<Problem> {
    let mut p = problem(model, scheme)?;
    let x = first_var(model);
    let x0 = match p.initial.get(x) {
        Some(Source::Const(v)) => *v,
        _ => 1.0,
    };
    let values = (0..16)
        .map(|i| x0 * (0.95 + 0.1 * i as f64 / 15.0))
        .collect();
    let ax = p.axis("x0", values);
    p = p.initial(x, ax);
    p.dt = Source::Const(0.05);
    p.steps = 60;
    // The comparison methods do not integrate the optional variable (p of
    // the Liénard systems).
    let spec = p.model.spec();
    let splitting = p.scheme.is_splitting();
    p.observers.final_vars = spec
        .vars
        .iter()
        .filter(|v| splitting || spec.optional_var != Some(**v))
        .map(|v| (*v).into())
        .collect();
    Some(p)
}

/// Every model × [`AGREEMENT_SCHEMES`] at `precision`.
fn agree(gpu: &Engine, precision: Precision) -> Vec<Agreement> {
    let hardware_exp = matches!(gpu, Engine::Gpu(c) if c.exp_f32 == ExpForm::Hardware);
    let tolerance = match (precision, hardware_exp) {
        (Precision::F32, false) => TOLERANCE_F32,
        (Precision::F32, true) => TOLERANCE_F32_HARDWARE_EXP,
        (Precision::F64, _) => TOLERANCE_F64,
    };
    let mut rows = vec![];
    for model in MODEL_NAMES {
        for scheme in AGREEMENT_SCHEMES {
            let Some(p) = ensemble(model, scheme) else {
                continue;
            };
            let (worst, error) = match difference(gpu, &p, precision) {
                Ok(w) => (w, None),
                Err(e) => (f64::NAN, Some(e)),
            };
            rows.push(Agreement {
                model: model.to_string(),
                scheme: scheme.to_string(),
                precision,
                worst,
                tolerance,
                pass: worst <= tolerance,
                error,
            });
        }
    }
    rows
}

/// max |gpu − cpu| / max(1, |cpu|) over the final values of `p`; infinite
/// where one backend's value is finite and the other's not.
fn difference(gpu: &Engine, p: &Problem, precision: Precision) -> Result<f64, String> {
    let plan = Plan::new(p).map_err(|e| e.to_string())?;
    let (g, _) = gpu.run_f64(&plan, precision).map_err(|e| e.to_string())?;
    let (c, _) = Engine::Cpu
        .run_f64(&plan, precision)
        .map_err(|e| e.to_string())?;
    Ok(largest_difference(&c, &g, false))
}

/// Repeats of each of the doctor's measurements (the median is reported).
const REPEATS: usize = 3;

/// [`BENCH_SCENARIOS`] × both precisions × `sizes` on the GPU (1000 steps,
/// more on a hardware adapter: [`bench::gpu_rate`]) and the CPU (every
/// thread; steps capped at 2·10⁹ trajectory-steps per run, at least 100:
/// the rate per trajectory-step is what counts).
fn throughput(
    gpu: Option<&Engine>,
    sizes: &[usize],
    progress: &mut impl FnMut(&str),
    problems: &mut Vec<String>,
) -> Vec<Row> {
    const STEPS: u64 = 1000;
    let mut rows = vec![];
    for s in BENCH_SCENARIOS {
        for p in [Precision::F32, Precision::F64] {
            for &n in sizes {
                progress(&format!("bench {} {p} n = {n}", s.label()));
                if let Some(g) = gpu {
                    match bench::gpu_rate(g, &s.plan(n, STEPS), p, REPEATS) {
                        Ok(Some((r, steps))) => {
                            let whole = whole_run(s, (n, steps), BackendChoice::Gpu, p, problems);
                            rows.push(row("gpu", s, p, (n, steps, 0), (r, whole)))
                        }
                        Ok(None) => {}
                        Err(e) => problems.push(format!("gpu {} {p} n = {n}: {e}", s.label())),
                    }
                }
                let steps = (2_000_000_000 / n as u64).clamp(100, STEPS);
                let threads = crate::backend::cpu::threads();
                let r = bench::cpu_rate(&s.plan(n, steps), p, threads, REPEATS);
                let whole = whole_run(s, (n, steps), BackendChoice::Cpu, p, problems);
                rows.push(row("cpu", s, p, (n, steps, threads), (r, whole)));
            }
        }
    }
    rows
}

/// The whole `reeb run` of scenario `s` at `size` (trajectory-steps/s on
/// every CPU thread); a failure is one of the report's problems.
fn whole_run(
    s: Scenario,
    size: (usize, u64),
    backend: BackendChoice,
    p: Precision,
    problems: &mut Vec<String>,
) -> Option<f64> {
    let threads = crate::backend::cpu::threads();
    bench::whole_run_rate(s, size, backend, p, threads, REPEATS)
        .map_err(|e| problems.push(format!("whole run {} {p}: {e:#}", s.label())))
        .ok()
}

/// A row of the report: `(n, steps, threads)` of the measurement, the
/// kernel's rate and the whole run's.
fn row(
    backend: &str,
    s: Scenario,
    p: Precision,
    size: (usize, u64, usize),
    (r, whole): (f64, Option<f64>),
) -> Row {
    Row {
        backend: backend.to_string(),
        scenario: s.label(),
        precision: p,
        n: size.0,
        steps: size.1,
        threads: size.2,
        traj_steps_per_s: r,
        whole_run_traj_steps_per_s: whole,
    }
}

impl Report {
    /// The table `reeb doctor` prints.
    pub fn table(&self) -> String {
        let mut t = String::new();
        let line = |t: &mut String, s: String| {
            t.push_str(&s);
            t.push('\n');
        };
        line(
            &mut t,
            format!("reeb {} doctor, {:.0} s", self.reeb, self.seconds),
        );
        line(
            &mut t,
            format!(
                "CPU: {}, {} kernels, {} threads",
                self.cpu.model, self.cpu.isa, self.cpu.threads
            ),
        );
        for (k, a) in self.adapters.iter().enumerate() {
            line(
                &mut t,
                format!(
                    "adapter {k}: {} ({}, {}, driver {}), f64 shaders {}",
                    a.name,
                    a.backend,
                    a.device_type,
                    a.driver,
                    if a.shader_f64 { "yes" } else { "no" }
                ),
            );
        }
        if let Some(a) = &self.adapter {
            line(&mut t, format!("checked: {a}"));
        }
        for v in &self.verify {
            line(
                &mut t,
                format!(
                    "verify gpu {}: {} passed, {} failed ({:.0} s)",
                    v.precision, v.passed, v.failed, v.seconds
                ),
            );
            for f in &v.failures {
                line(&mut t, format!("  FAIL {f}"));
            }
        }
        for p in [Precision::F32, Precision::F64] {
            let rows: Vec<&Agreement> =
                self.agreement.iter().filter(|a| a.precision == p).collect();
            if rows.is_empty() {
                continue;
            }
            let worst = rows.iter().map(|a| a.worst).fold(0.0, f64::max);
            let failed: Vec<String> = rows
                .iter()
                .filter(|a| !a.pass)
                .map(|a| format!("{} {} ({:e})", a.model, a.scheme, a.worst))
                .collect();
            line(
                &mut t,
                format!(
                    "agreement {p}: {} of {} within {:e} (worst {worst:.1e}){}",
                    rows.len() - failed.len(),
                    rows.len(),
                    rows[0].tolerance,
                    if failed.is_empty() {
                        String::new()
                    } else {
                        format!("; outside: {}", failed.join(", "))
                    }
                ),
            );
        }
        line(
            &mut t,
            format!(
                "{:<6} {:<24} {:>9} {:>10} {:>6} {:>14} {:>14}",
                "", "scenario", "precision", "n", "steps", "traj-steps/s", "whole run"
            ),
        );
        for e in &self.exp {
            line(
                &mut t,
                format!(
                    "f32 exp, {}{}: within {:.2} ULP over {} arguments (worst at x = {}; bound {}){}",
                    e.accuracy.form.name(),
                    if e.in_use { " (in use)" } else { "" },
                    e.accuracy.max_ulp,
                    e.accuracy.points,
                    e.accuracy.at,
                    e.bound,
                    if e.pass { "" } else { " FAIL" }
                ),
            );
        }
        for b in &self.bench {
            line(
                &mut t,
                format!(
                    "{:<6} {:<24} {:>9} {:>10} {:>6} {:>14.3e} {:>14}",
                    b.backend,
                    b.scenario,
                    b.precision,
                    b.n,
                    b.steps,
                    b.traj_steps_per_s,
                    b.whole_run_traj_steps_per_s
                        .map_or("-".to_string(), |w| format!("{w:.3e}"))
                ),
            );
        }
        for r in &self.tuning {
            line(
                &mut t,
                format!(
                    "tuned {:<24} {:<58} GPU {:.3e}, CPU {:.3e} traj-steps/s",
                    r.shape, r.launch, r.gpu_rate, r.cpu_rate
                ),
            );
        }
        for p in &self.problems {
            line(&mut t, format!("note: {p}"));
        }
        t
    }

    /// Was there a GPU to check, and did every check pass (verify and
    /// agreement)?
    pub fn healthy(&self) -> bool {
        self.adapter.is_some()
            && self.verify.iter().all(|v| v.failed == 0)
            && self.agreement.iter().all(|a| a.pass)
            && self.exp.iter().all(|e| e.pass || !e.in_use)
    }
}
