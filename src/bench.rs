//! Throughput benchmarks: `reeb bench` and `benches/throughput.rs` run the
//! same scenarios. Rates are trajectory-steps per second of the integration
//! alone (no kernel compilation, no upload: the GPU timing is the dispatches'),
//! as the median of several repeats; beside them, the rate of the whole
//! `reeb run` of the same ensemble as a scene, from reading the scene to
//! its arrays, pictures and summary on disk.

pub mod indicators;

use std::time::Instant;

use crate::backend::BackendError;
use crate::backend::{BackendChoice, Engine};
use crate::models::Model;
use crate::num::precision::Precision;
use crate::plan::{Plan, Problem, Source};

/// A benchmark scenario: a plan family parameterised by ensemble size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scenario {
    /// Van der Pol S2(CBABC), (q, s) only, per-trajectory ε, dt = 0.01,
    /// final state only: the job of `../shared/peers`.
    VdpS2,
    /// The same with the slope variable p integrated too (what the
    /// specialisation leaves out).
    VdpS2WithP,
    /// Van der Pol, Yoshida 6A.
    VdpYoshida6a,
    /// Spin–orbit S2 (e = 0.06, ε = 0.045, λ = 0.01, Ω = √2), per-trajectory p0.
    SpinOrbitS2,
    /// Perturbed Kepler S2 (α = 0.01, θ = 2π), per-trajectory eccentricity.
    KeplerS2,
    /// Van der Pol written as Liénard formulas (`f = -epsilon*(1 - q^2)`,
    /// `g = q`), S2, the ensemble of `VdpS2`: what a formula model costs.
    LienardFormulaS2,
}

pub const SCENARIOS: [Scenario; 6] = [
    Scenario::VdpS2,
    Scenario::VdpS2WithP,
    Scenario::VdpYoshida6a,
    Scenario::SpinOrbitS2,
    Scenario::KeplerS2,
    Scenario::LienardFormulaS2,
];

impl Scenario {
    /// `model/scheme` label of criterion groups and `reeb bench` rows.
    pub fn label(self) -> &'static str {
        match self {
            Scenario::VdpS2 => "van_der_pol/s2",
            Scenario::VdpS2WithP => "van_der_pol/s2_with_p",
            Scenario::VdpYoshida6a => "van_der_pol/yoshida6a",
            Scenario::SpinOrbitS2 => "spin_orbit/s2",
            Scenario::KeplerS2 => "kepler/s2",
            Scenario::LienardFormulaS2 => "lienard_formula/s2",
        }
    }

    pub fn by_label(label: &str) -> Option<Scenario> {
        SCENARIOS.iter().copied().find(|s| s.label() == label)
    }

    /// The plan for `n` trajectories and `steps` steps.
    pub fn plan(self, n: usize, steps: u64) -> Plan {
        let frac = |i: usize| i as f64 / n as f64;
        let mut p = match self {
            Scenario::VdpS2
            | Scenario::VdpS2WithP
            | Scenario::VdpYoshida6a
            | Scenario::LienardFormulaS2 => {
                let scheme = if self == Scenario::VdpYoshida6a {
                    "yoshida6a"
                } else {
                    "s2"
                };
                let model = if self == Scenario::LienardFormulaS2 {
                    formula_van_der_pol()
                } else {
                    Model::VanDerPol
                };
                let mut p = Problem::new(model, scheme).expect("scheme");
                // The peers' ensemble: q0 = 2 + 0.5 i/N, ε = 0.1 + 10 i/N, s0 = 0.
                let q0 = p.axis("i", (0..n).map(|i| 2.0 + 0.5 * frac(i)).collect());
                p = p.initial("q", q0).param(
                    "epsilon",
                    Source::Axis {
                        axis: 0,
                        values: (0..n).map(|i| 0.1 + 10.0 * frac(i)).collect(),
                    },
                );
                if self == Scenario::VdpS2WithP {
                    p = p.initial("p", Source::Const(-1.0));
                    p.observers.final_vars = vec!["q".into(), "s".into(), "p".into()];
                }
                p
            }
            Scenario::SpinOrbitS2 => {
                let mut p = Problem::new(Model::SpinOrbit, "s2")
                    .expect("s2")
                    .param("eccentricity", Source::Const(0.06))
                    .param("epsilon", Source::Const(0.045))
                    .param("lambda", Source::Const(0.01))
                    .param("omega", Source::Const(std::f64::consts::SQRT_2));
                let p0 = p.axis("i", (0..n).map(|i| 0.4 + 1.4 * frac(i)).collect());
                p.initial("p", p0)
            }
            Scenario::KeplerS2 => {
                let mut p = Problem::new(Model::Kepler, "s2")
                    .expect("s2")
                    .param("alpha", Source::Const(0.01))
                    .param("theta", Source::Const(std::f64::consts::TAU));
                let e: Vec<f64> = (0..n).map(|i| 0.5 * frac(i)).collect();
                let q1 = p.axis("i", e.iter().map(|e| 1.0 - e).collect());
                p.initial("q1", q1).initial(
                    "p2",
                    Source::Axis {
                        axis: 0,
                        values: e.iter().map(|e| ((1.0 + e) / (1.0 - e)).sqrt()).collect(),
                    },
                )
            }
        };
        p.dt = Source::Const(0.01);
        p.steps = steps;
        Plan::new(&p).expect("benchmark plans are valid")
    }

    /// The scene a user would write for this scenario at `n` trajectories
    /// and `steps` steps: its model, scheme and step, one axis of `n`
    /// values (the plan's paired axes as near as a scene says them:
    /// van der Pol's ε sweep from q = 2, spin–orbit's p0, Kepler's
    /// eccentricity) and its final states.
    pub fn scene_text(self, n: usize, steps: u64) -> String {
        let vdp = |model: &str, formula: &str, p: &str| {
            format!("model = \"{model}\"\n{formula}\n[params]\nepsilon = {{ linspace = [0.1, 10.1, {n}] }}\n\n[initial]\nq = 2.0\ns = 0.0\n{p}")
        };
        let qs = "\"q\", \"s\"";
        let (head, scheme, finals) = match self {
            Scenario::VdpS2 => (vdp("van_der_pol", "", ""), "s2", qs),
            Scenario::VdpS2WithP => (
                vdp("van_der_pol", "", "p = -1.0\n"),
                "s2",
                "\"q\", \"s\", \"p\"",
            ),
            Scenario::VdpYoshida6a => (vdp("van_der_pol", "", ""), "yoshida6a", qs),
            Scenario::LienardFormulaS2 => (
                vdp(
                    "lienard",
                    "\n[formula]\nf = \"-epsilon*(1 - q^2)\"\ng = \"q\"\n",
                    "",
                ),
                "s2",
                qs,
            ),
            Scenario::SpinOrbitS2 => (
                format!(
                    "model = \"spin_orbit\"\n\n[params]\neccentricity = 0.06\nepsilon = 0.045\nlambda = 0.01\nomega = {}\n\n[initial]\nq = 0.0\np = {{ linspace = [0.4, 1.8, {n}] }}\n",
                    std::f64::consts::SQRT_2
                ),
                "s2",
                "\"q\", \"p\"",
            ),
            Scenario::KeplerS2 => (
                format!(
                    "model = \"kepler\"\n\n[params]\nalpha = 0.01\ntheta = {}\n\n[initial]\neccentricity = {{ linspace = [0.0, 0.5, {n}] }}\n",
                    std::f64::consts::TAU
                ),
                "s2",
                "\"q\", \"p\"",
            ),
        };
        format!(
            "name = \"bench_{}\"\n{head}\n[integrator]\nscheme = \"{scheme}\"\ndt = 0.01\nsteps = {steps}\n\n[output]\nfinal = [{finals}]\n",
            self.label().replace('/', "_")
        )
    }
}

/// What `reeb bench` measures.
pub struct BenchOptions {
    /// "cpu", "gpu"; empty: the CPU, and the GPU when an adapter exists.
    pub backends: Vec<String>,
    /// Empty: every scenario.
    pub scenarios: Vec<Scenario>,
    pub precisions: Vec<Precision>,
    pub sizes: Vec<usize>,
    pub steps: u64,
    /// CPU thread counts; empty: 1 and every thread.
    pub threads: Vec<usize>,
    pub repeats: usize,
}

/// One measurement: `backend` is "cpu" or "gpu: <adapter>" ("gpu" in
/// `reeb doctor`'s report, which names the adapter once), `threads` 0 on
/// the GPU.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Row {
    pub backend: String,
    pub scenario: &'static str,
    pub precision: Precision,
    pub n: usize,
    pub steps: u64,
    pub threads: usize,
    pub traj_steps_per_s: f64,
    /// The whole `reeb run` of the same size ([`whole_run_rate`]): on the
    /// GPU, and on the CPU at every thread.
    pub whole_run_traj_steps_per_s: Option<f64>,
}

/// Every backend × scenario × precision × size (× thread count on the CPU),
/// in that order, handing each row to `each` as it is measured.
pub fn run(opts: &BenchOptions, mut each: impl FnMut(&Row)) -> Result<(), String> {
    let engines = engines(&opts.backends)?;
    let scenarios = match opts.scenarios.is_empty() {
        true => SCENARIOS.to_vec(),
        false => opts.scenarios.clone(),
    };
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = match (opts.threads.is_empty(), all > 1) {
        (false, _) => opts.threads.clone(),
        (true, true) => vec![1, all],
        (true, false) => vec![1],
    };
    for (name, engine) in engines.each() {
        for &s in &scenarios {
            for &p in &opts.precisions {
                for &n in &opts.sizes {
                    let plan = s.plan(n, opts.steps);
                    let row = |backend: String, threads, r| Row {
                        backend,
                        scenario: s.label(),
                        precision: p,
                        n,
                        steps: opts.steps,
                        threads,
                        traj_steps_per_s: r,
                        whole_run_traj_steps_per_s: None,
                    };
                    let whole = |backend, steps, threads| {
                        whole_run_rate(s, (n, steps), backend, p, threads, opts.repeats)
                            .map(Some)
                            .map_err(|e| format!("{} {}: whole run: {e:#}", name, s.label()))
                    };
                    match engine {
                        Engine::Gpu(_) => match gpu_rate(engine, &plan, p, opts.repeats) {
                            Ok(Some((r, steps))) => each(&Row {
                                steps,
                                whole_run_traj_steps_per_s: whole(BackendChoice::Gpu, steps, all)?,
                                ..row(name.clone(), 0, r)
                            }),
                            Ok(None) => {}
                            Err(e) => return Err(format!("gpu {}: {e}", s.label())),
                        },
                        Engine::Cpu => {
                            for &t in &threads {
                                let r = cpu_rate(&plan, p, t, opts.repeats);
                                each(&Row {
                                    whole_run_traj_steps_per_s: match t == all {
                                        true => whole(BackendChoice::Cpu, opts.steps, t)?,
                                        false => None,
                                    },
                                    ..row("cpu".into(), t, r)
                                });
                            }
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// The engines a benchmark runs on, in the order asked for.
pub struct Engines {
    cpu: Engine,
    gpu: Option<Engine>,
    order: Vec<String>,
}

/// The engines `backends` names ("cpu", "gpu"); none named: the CPU, and
/// the GPU when an adapter exists.
pub fn engines(backends: &[String]) -> Result<Engines, String> {
    if let Some(b) = backends
        .iter()
        .find(|b| !["cpu", "gpu"].contains(&b.as_str()))
    {
        return Err(format!("--backend: unknown backend `{b}` (cpu or gpu)"));
    }
    // A device is opened only when the GPU may be measured.
    let asked = |b: &str| backends.is_empty() || backends.iter().any(|x| x == b);
    let gpu = match asked("gpu").then(|| Engine::gpu(None)) {
        Some(Ok(g)) => Some(g),
        Some(Err(e)) if !backends.is_empty() => return Err(format!("--backend gpu: {e}")),
        _ => None,
    };
    let order = match (backends.is_empty(), gpu.is_some()) {
        (false, _) => backends.to_vec(),
        (true, true) => vec!["cpu".into(), "gpu".into()],
        (true, false) => vec!["cpu".into()],
    };
    Ok(Engines {
        cpu: Engine::Cpu,
        gpu,
        order,
    })
}

impl Engines {
    /// Each engine with its name in the rows: "cpu", "gpu: <adapter>".
    pub fn each(&self) -> impl Iterator<Item = (String, &Engine)> {
        self.order
            .iter()
            .filter_map(|b| match (b.as_str(), &self.gpu) {
                ("gpu", Some(g @ Engine::Gpu(c))) => Some((format!("gpu: {}", c.info.name), g)),
                ("gpu", _) => None,
                _ => Some(("cpu".to_string(), &self.cpu)),
            })
    }
}

/// Van der Pol as a Liénard scene's formulas.
fn formula_van_der_pol() -> Model {
    use crate::models::formula::{FormulaModel, Kind, Source as Formulas};
    let source = Formulas {
        kind: Kind::Lienard,
        texts: vec![
            ("f".into(), "-epsilon*(1 - q^2)".into()),
            ("g".into(), "q".into()),
        ],
        params: vec!["epsilon".into()],
        forcing_frequency: None,
    };
    Model::Formula(FormulaModel::get(&source).expect("valid formulas"))
}

/// Median trajectory-steps/s of the whole `reeb run` of `s`'s scene at
/// `(n, steps)` on `backend` with `threads` CPU threads, after a first run
/// that warms the caches: wall seconds from reading the scene to the
/// summary written, into a directory of its own under the system's
/// temporary one (removed afterwards).
pub fn whole_run_rate(
    s: Scenario,
    (n, steps): (usize, u64),
    backend: BackendChoice,
    precision: Precision,
    threads: usize,
    repeats: usize,
) -> anyhow::Result<f64> {
    use crate::output::run::{run_scene, RunOptions, TaskOptions};
    let dir = std::env::temp_dir().join(format!("reeb-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let path = dir.join("scene.toml");
    let text = s.scene_text(n, steps);
    std::fs::write(&path, &text)?;
    let once = || -> anyhow::Result<f64> {
        let started = Instant::now();
        let scene = crate::scene::Scene::parse(&path, &text)?;
        let opts = RunOptions {
            out: Some(dir.join("run")),
            force: true,
            task: TaskOptions {
                backend: Some(backend),
                precision: Some(precision),
                ..TaskOptions::default()
            },
            started: Some(started),
            ..RunOptions::default()
        };
        run_scene(&scene, &opts)?;
        Ok(started.elapsed().as_secs_f64())
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let times: anyhow::Result<Vec<f64>> =
        pool.install(|| (0..=repeats.max(1)).map(|_| once()).collect());
    let _ = std::fs::remove_dir_all(&dir);
    let times = times?;
    Ok((n as u64 * steps) as f64 / median(times[1..].to_vec()))
}

/// Median trajectory-steps/s of `plan` on the CPU with `threads` threads.
pub fn cpu_rate(plan: &Plan, precision: Precision, threads: usize, repeats: usize) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        rate(plan, repeats, true, |pl| {
            seconds(&Engine::Cpu, pl, precision).unwrap_or(f64::NAN)
        })
    })
}

/// Kernel seconds a timed GPU run lasts at least on a hardware adapter. A
/// GPU raises its clocks only while busy (an H200 idles at 345 MHz, runs at
/// 1980 and drops within a quarter second): a run of milliseconds between
/// the host's set-up and read-back of 10⁷ trajectories is timed at idle
/// clocks, up to 6× slow.
pub const GPU_RUN_SECONDS: f64 = 0.25;
/// The most a GPU run is lengthened by, as a multiple of its steps.
const MOST_LENGTHENED: u64 = 1000;

/// Median trajectory-steps/s of `plan` on the GPU `engine`, and the steps
/// per run it was measured at: `plan`'s, lengthened on a hardware adapter
/// until a run takes [`GPU_RUN_SECONDS`] (the rate is per trajectory-step;
/// every step of a benchmark plan costs the same). `None` for f64 on an
/// adapter without SHADER_F64.
pub fn gpu_rate(
    engine: &Engine,
    plan: &Plan,
    precision: Precision,
    repeats: usize,
) -> Result<Option<(f64, u64)>, BackendError> {
    let Engine::Gpu(ctx) = engine else {
        return Ok(None);
    };
    if !engine.runs(precision) {
        return Ok(None);
    }
    let mut plan = plan.clone();
    let most = plan.steps.saturating_mul(MOST_LENGTHENED);
    // Whether the last run was at the final length: then it was the warm-up.
    let mut warmed = false;
    if !crate::backend::gpu::is_software(&ctx.info) {
        // Each run both warms the GPU and times it; the runs that follow a
        // cold first one are shorter, so a few rounds settle the length.
        for _ in 0..4 {
            let t = seconds(engine, &plan, precision)?;
            warmed = true;
            if t >= GPU_RUN_SECONDS || plan.steps >= most {
                break;
            }
            let k = (GPU_RUN_SECONDS / t.max(1e-6)).ceil() as u64;
            plan.steps = plan.steps.saturating_mul(k.max(2)).min(most);
            warmed = false;
        }
    }
    let mut err = None;
    let r = rate(&plan, repeats, !warmed, |pl| {
        seconds(engine, pl, precision).unwrap_or_else(|e| {
            err = Some(e);
            f64::NAN
        })
    });
    match err {
        Some(e) => Err(e),
        None => Ok(Some((r, plan.steps))),
    }
}

/// Median of a sample.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::NAN
    } else if v.len() % 2 == 1 {
        v[v.len() / 2]
    } else {
        0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2])
    }
}

/// Seconds of one integration of `plan` on `engine`, as the backend times it
/// (wall clock on the CPU; timestamp queries on a GPU that has them, after
/// the first call has compiled and cached the kernel).
pub fn seconds(engine: &Engine, plan: &Plan, precision: Precision) -> Result<f64, BackendError> {
    Ok(match precision {
        Precision::F32 => engine.run::<f32>(plan, None)?.phases.integration,
        Precision::F64 => engine.run::<f64>(plan, None)?.phases.integration,
    })
}

/// Median trajectory-steps per second over `repeats` runs, after one
/// warm-up run if `warm` (the first run compiles and caches the kernel).
pub fn rate(plan: &Plan, repeats: usize, warm: bool, mut once: impl FnMut(&Plan) -> f64) -> f64 {
    if warm {
        once(plan);
    }
    let times: Vec<f64> = (0..repeats.max(1)).map(|_| once(plan)).collect();
    plan.traj_steps() as f64 / median(times)
}

/// One plan shape tuned by `reeb tune`.
pub struct Tuning {
    pub shape: String,
    pub tuned: crate::backend::gpu::tuning::Tuned,
}

/// `reeb tune`: probes again, on `engine`'s adapter, the plan shapes of
/// `scene` (its sub-runs), or those of the benchmark scenarios, in each of
/// `precisions` the adapter runs, and caches them; `row` sees each.
pub fn tune(
    engine: &Engine,
    scene: Option<&crate::scene::Scene>,
    precisions: &[Precision],
    mut row: impl FnMut(&Tuning),
) -> Result<Vec<Tuning>, BackendError> {
    use crate::backend::tune;
    let Engine::Gpu(ctx) = engine else {
        return Ok(vec![]);
    };
    let plans: Vec<Plan> = match scene {
        Some(s) => s
            .sub_runs()
            .map_err(|e| BackendError::Tuning(e.to_string()))?
            .into_iter()
            .map(|r| r.plan)
            .collect(),
        None => SCENARIOS.iter().map(|s| s.plan(1 << 20, 1000)).collect(),
    };
    let mut out: Vec<Tuning> = vec![];
    for &p in precisions.iter().filter(|p| engine.runs(**p)) {
        for plan in &plans {
            let shape = tune::shape(ctx, plan, p);
            if out.iter().any(|t| t.shape == shape) {
                continue;
            }
            let tuned = tune::tuned(ctx, plan, p, true)?;
            let t = Tuning { shape, tuned };
            row(&t);
            out.push(t);
        }
    }
    Ok(out)
}
