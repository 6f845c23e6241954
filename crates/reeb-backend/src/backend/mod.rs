//! Backends: the CPU (rayon) and the GPU (wgpu). Both execute a [`Plan`] and
//! return the same [`Observations`]. This file is the one way in: the choice
//! of backend ([`BackendChoice`] → [`Engine`]) and the one dispatch path
//! ([`Engine::run`]) that `reeb run`, reports, `verify` and `bench` all use.

pub mod checkpoint;
pub mod cpu;
pub mod error;
pub mod gpu;
pub mod phases;
pub mod tune;

use std::sync::atomic::{AtomicBool, AtomicU64};

use crate::models::Flows;
use crate::num::precision::Precision;
use crate::plan::observations::Observations;
use crate::plan::snapshot::Header;
use crate::plan::Plan;
use checkpoint::Checkpoints;
pub use error::BackendError;
use gpu::{GpuContext, GpuError};
pub use phases::Phases;

/// Which backend a run asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendChoice {
    /// A hardware GPU adapter if there is one, else the CPU (with a notice).
    Auto,
    Cpu,
    Gpu,
}

impl std::str::FromStr for BackendChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(BackendChoice::Auto),
            "cpu" => Ok(BackendChoice::Cpu),
            "gpu" => Ok(BackendChoice::Gpu),
            _ => Err(format!("`{s}` is not a backend (auto, cpu, gpu)")),
        }
    }
}

impl BackendChoice {
    /// The name a scene and `--backend` use.
    pub fn name(self) -> &'static str {
        match self {
            BackendChoice::Auto => "auto",
            BackendChoice::Cpu => "cpu",
            BackendChoice::Gpu => "gpu",
        }
    }
}

/// `--adapters`: the GPU adapters one run spreads its chunks over.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Adapters {
    /// Every hardware GPU of the machine.
    All,
    /// These, by their index in `reeb info`'s list (one twice: two
    /// devices on one adapter).
    List(Vec<usize>),
}

impl std::str::FromStr for Adapters {
    type Err = String;
    fn from_str(s: &str) -> Result<Adapters, String> {
        if s.trim() == "all" {
            return Ok(Adapters::All);
        }
        let list = s
            .split(',')
            .map(|k| {
                k.trim().parse::<usize>().map_err(|_| {
                    format!("`{k}` is not an adapter index (`all`, or indices as `reeb info` numbers them, e.g. 0,1)")
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Adapters::List(list))
    }
}

impl std::fmt::Display for Adapters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Adapters::All => write!(f, "all"),
            Adapters::List(v) => {
                let v: Vec<String> = v.iter().map(usize::to_string).collect();
                write!(f, "{}", v.join(","))
            }
        }
    }
}

/// The backend a run ends up on.
pub enum Engine {
    Cpu,
    Gpu(Box<GpuContext>),
}

/// One integration: the observations and how long each phase took.
pub struct Integration<R> {
    pub observations: Observations<R>,
    /// Set-up, compilation, integration and read-back (the outputs' phases 0).
    pub phases: Phases,
    /// How the integration was timed: "wall clock" or "GPU timestamps".
    pub timing: &'static str,
    /// When a GPU's queue was this integration's (none on the CPU).
    pub busy: Vec<(std::time::Instant, std::time::Instant)>,
}

/// A device on adapter `index` (or the one `--backend gpu` takes), its
/// hardware exp kept only where it measures accurate (`gpu::accuracy`).
fn open(index: Option<usize>) -> Result<GpuContext, GpuError> {
    let mut ctx = GpuContext::on(index)?;
    gpu::accuracy::settle_exp(&mut ctx);
    Ok(ctx)
}

impl Engine {
    /// Chooses the backend. `auto` takes a hardware GPU adapter when there is
    /// one (and it has f64 if asked for), and otherwise the CPU, returning
    /// the one-line notice to print. A software adapter (lavapipe) is slower
    /// than the CPU backend, so `auto` uses it only when asked with `gpu`.
    pub fn resolve(
        choice: BackendChoice,
        precision: Precision,
    ) -> Result<(Engine, Option<String>), BackendError> {
        Engine::resolve_for(choice, precision, None, None)
    }

    /// [`Engine::resolve`] with the GPU pinned to adapter `index` (`--adapter`:
    /// one shard per GPU of a node), and, given the `plan` to run, `auto`
    /// taking the faster of that GPU and the CPU for the plan's shape, as
    /// the tuning probe measured them (`tune.rs`); the notice says which
    /// and why. With `--adapter`, `auto` weighs even a software adapter.
    pub fn resolve_for(
        choice: BackendChoice,
        precision: Precision,
        index: Option<usize>,
        plan: Option<&Plan>,
    ) -> Result<(Engine, Option<String>), BackendError> {
        let f64_missing = |ctx: &GpuContext| precision == Precision::F64 && !ctx.shader_f64;
        if choice == BackendChoice::Cpu {
            return Ok((Engine::Cpu, None));
        }
        // `gpu` or `auto` from here.
        let ctx = match open(index) {
            // A setting the user got wrong is an error, not a missing GPU.
            Err(e @ GpuError::Setting(_)) => return Err(e.into()),
            ctx if choice == BackendChoice::Gpu => {
                let ctx = ctx?;
                tune::check_env(&ctx)?;
                if f64_missing(&ctx) {
                    return Err(GpuError::NoF64(ctx.describe()).into());
                }
                return Ok((Engine::Gpu(Box::new(ctx)), None));
            }
            Err(e) if index.is_none() => {
                return Ok((
                    Engine::Cpu,
                    Some(format!(
                        "note: no GPU adapter ({}); running on the CPU",
                        first_line(&e.to_string())
                    )),
                ))
            }
            ctx => ctx?,
        };
        if index.is_none() && gpu::is_software(&ctx.info) {
            return Ok((Engine::Cpu, Some(format!("note: only a software GPU adapter ({}); running on the CPU (use --backend gpu to run it anyway)", ctx.info.name))));
        }
        if f64_missing(&ctx) {
            return Ok((
                Engine::Cpu,
                Some(format!(
                    "note: {} has no f64 shaders; running on the CPU",
                    ctx.info.name
                )),
            ));
        }
        tune::check_env(&ctx)?;
        let Some(plan) = plan else {
            return Ok((Engine::Gpu(Box::new(ctx)), None));
        };
        match tune::tuned(&ctx, plan, precision, false) {
            Ok(t) => {
                // On the whole run: a short one may spend more on the
                // GPU's host work than the GPU saves.
                let size = (plan.n as u64, plan.steps);
                let (gpu_s, cpu_s) = t.whole_run_seconds(size.0, size.1);
                let gpu = gpu_s <= cpu_s;
                let notice = tune::auto_notice(&ctx.info.name, precision, &t, size);
                let engine = match gpu {
                    true => Engine::Gpu(Box::new(ctx)),
                    false => Engine::Cpu,
                };
                Ok((engine, Some(notice)))
            }
            Err(e) => Ok((
                Engine::Cpu,
                Some(format!(
                    "note: measuring {} failed ({}); running on the CPU",
                    ctx.info.name,
                    first_line(&e.to_string())
                )),
            )),
        }
    }

    /// One GPU engine for each adapter of `adapters` (`--adapters`), each
    /// with its own device and queue, and the notice naming them.
    pub fn resolve_many(
        precision: Precision,
        adapters: &Adapters,
    ) -> Result<(Vec<Engine>, String), BackendError> {
        let indices = match adapters {
            Adapters::All => gpu::every_gpu()?,
            Adapters::List(v) => v.clone(),
        };
        let mut engines = vec![];
        for k in indices {
            let ctx = open(Some(k))?;
            tune::check_env(&ctx)?;
            if precision == Precision::F64 && !ctx.shader_f64 {
                return Err(GpuError::NoF64(ctx.describe()).into());
            }
            engines.push(Engine::Gpu(Box::new(ctx)));
        }
        let names: Vec<String> = engines.iter().filter_map(Engine::adapter).collect();
        let notice = format!(
            "note: {} GPU devices, the chunks shared among them: {}",
            names.len(),
            names.join("; ")
        );
        Ok((engines, notice))
    }

    /// `adapter K: NAME` for a GPU engine.
    pub fn adapter(&self) -> Option<String> {
        match self {
            Engine::Cpu => None,
            Engine::Gpu(ctx) => Some(format!("adapter {}: {}", ctx.index, ctx.info.name)),
        }
    }

    /// The GPU backend on adapter `index` of `reeb info`'s list, or on the
    /// one `--backend gpu` takes: the one way a GPU engine is built.
    pub fn gpu(index: Option<usize>) -> Result<Engine, BackendError> {
        Ok(Engine::Gpu(Box::new(open(index)?)))
    }

    /// Does this engine run `precision`? A GPU without SHADER_F64 runs f32 only.
    pub fn runs(&self, precision: Precision) -> bool {
        match self {
            Engine::Cpu => true,
            Engine::Gpu(ctx) => precision == Precision::F32 || ctx.shader_f64,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Engine::Cpu => "cpu",
            Engine::Gpu(_) => "gpu",
        }
    }

    /// The CPU kernels' instruction set (`x86-64-v3`, …) when this engine
    /// is the CPU: what makes its results differ in the last bits.
    pub fn cpu_isa(&self) -> Option<String> {
        match self {
            Engine::Cpu => Some(cpu::kernels::isa().name().to_string()),
            Engine::Gpu(_) => None,
        }
    }

    pub fn describe(&self) -> String {
        match self {
            Engine::Cpu => format!("cpu ({} threads)", cpu::threads()),
            Engine::Gpu(ctx) => format!("gpu: {}", ctx.describe()),
        }
    }

    /// Integrates `plan` in precision `R`; `progress`, if given, counts
    /// trajectory-steps as they finish.
    pub fn run<R: Flows>(
        &self,
        plan: &Plan,
        progress: Option<&AtomicU64>,
    ) -> Result<Integration<R>, BackendError> {
        self.run_resumable(plan, progress, None)
    }

    /// [`Engine::run`] with checkpoints: continues from `cp`'s snapshot if
    /// it has one, and takes one whenever it is due.
    pub fn run_resumable<R: Flows>(
        &self,
        plan: &Plan,
        progress: Option<&AtomicU64>,
        cp: Option<&mut Checkpoints>,
    ) -> Result<Integration<R>, BackendError> {
        Ok(match self {
            Engine::Cpu => {
                // Arrays whose lengths overflow are refused, not allocated.
                Observations::<R>::lengths(plan).map_err(BackendError::TooLarge)?;
                let (observations, phases) = cpu::resumable::<R>(plan, progress, cpu::isa(), cp)?;
                Integration {
                    observations,
                    phases,
                    timing: "wall clock",
                    busy: vec![],
                }
            }
            Engine::Gpu(ctx) => {
                let opts = Engine::launch::<R>(ctx, plan)?;
                let r = gpu::run_resumable::<R>(ctx, plan, progress, &opts, cp)?;
                Integration {
                    observations: r.observations,
                    phases: r.phases,
                    timing: r.timing,
                    busy: r.busy,
                }
            }
        })
    }

    /// The header a snapshot of `plan` taken by this engine has (a
    /// snapshot continues only on the engine that computes the same bits).
    pub fn snapshot_header<R: Flows>(&self, plan: &Plan) -> Result<Header, BackendError> {
        let engine = match self {
            Engine::Cpu => cpu::fingerprint(cpu::isa()),
            Engine::Gpu(ctx) => gpu::fingerprint::<R>(ctx, plan, &Engine::launch::<R>(ctx, plan)?)?,
        };
        Ok(Header::of::<R>(plan, engine))
    }

    /// The GPU options of `plan`: its launch tuned for this adapter.
    fn launch<R: Flows>(ctx: &GpuContext, plan: &Plan) -> Result<gpu::GpuOptions, BackendError> {
        Ok(gpu::GpuOptions {
            launch: Some(tune::launch_for(ctx, plan, Precision::of::<R>())?),
            ..Default::default()
        })
    }

    /// [`Engine::run`] in a precision chosen at run time, widened to f64 for
    /// analysis (reports, verify); also returns the seconds.
    pub fn run_f64(
        &self,
        plan: &Plan,
        precision: Precision,
    ) -> Result<(Observations<f64>, f64), BackendError> {
        self.run_f64_until(plan, precision, None)
    }

    /// [`Engine::run_f64`] that ends with `BackendError::Stopped` soon after
    /// `stop` is set (Ctrl-C in Python).
    pub fn run_f64_until(
        &self,
        plan: &Plan,
        precision: Precision,
        stop: Option<&AtomicBool>,
    ) -> Result<(Observations<f64>, f64), BackendError> {
        let mut save = |_: checkpoint::Contents| Ok(());
        let mut cp = stop.map(|s| Checkpoints {
            every: None,
            since: std::time::Instant::now(),
            resume: None,
            save: &mut save,
            taken: 0,
            stop: Some(s),
        });
        Ok(match precision {
            Precision::F32 => {
                let r = self.run_resumable::<f32>(plan, None, cp.as_mut())?;
                (r.observations.convert(), r.phases.integration)
            }
            Precision::F64 => {
                let r = self.run_resumable::<f64>(plan, None, cp.as_mut())?;
                (r.observations, r.phases.integration)
            }
        })
    }
}

fn first_line(s: &str) -> &str {
    s.lines().next().unwrap_or(s)
}
