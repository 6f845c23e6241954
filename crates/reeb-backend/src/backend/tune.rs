//! The GPU launch for an adapter and a plan shape, chosen by a short probe
//! (about a second, once: the result is cached, `gpu/tuning.rs`), which
//! also measures the CPU backend on the same plan so that `--backend auto`
//! can take the faster of the two (an f64 run on a GPU with 1/64-rate f64
//! can be slower than the CPU).

use std::time::Instant;

use super::cpu;
use super::error::BackendError;
use super::gpu::tuning::{
    adapter_key, Cache, Launch, Overrides, Tuned, FINITE_BLOCKS, GPU_FINITE_BLOCK, PER_THREAD,
    WORKGROUPS,
};
use super::gpu::{self, GpuContext, GpuOptions};
use crate::models::Flows;
use crate::num::precision::Precision;
use crate::plan::Plan;

/// Wall seconds the probe aims to stay within.
pub const PROBE_SECONDS: f64 = 1.0;
/// Wall seconds of one measurement.
const MEASURE_SECONDS: f64 = 0.04;
/// Most steps of one measurement (an H200 runs 2^20 trajectories × 4096
/// steps of van der Pol in 3 ms).
const MOST_STEPS: u64 = 1 << 16;
/// Set (to anything), the probe prints each candidate's rate to stderr.
pub const PROBE_LOG: &str = "REEB_GPU_PROBE_LOG";

/// The plan shape a tuning is kept for: precision, model (its state, its
/// pieces' cost, its registers) and the probe's size class (2^0, 2^4, …
/// trajectories: a GPU that 16 trajectories leave idle may win at 10⁶).
pub fn shape(ctx: &GpuContext, plan: &Plan, precision: Precision) -> String {
    let k = probe_size(ctx, plan).ilog2() / 4 * 4;
    format!("{} {} 2^{k}", precision.name(), plan.model.name())
}

/// Trajectories the probe measures: the plan's, up to 2^20 (2^14 on a
/// software adapter).
fn probe_size(ctx: &GpuContext, plan: &Plan) -> usize {
    let most = match gpu::is_software(&ctx.info) {
        true => 1 << 14,
        false => 1 << 20,
    };
    plan.n.clamp(1, most)
}

/// The environment's overrides, checked against `ctx`'s limits (before a
/// run claims its directory).
pub fn check_env(ctx: &GpuContext) -> Result<(), BackendError> {
    let env = Overrides::from_env().map_err(BackendError::Tuning)?;
    env.apply(Launch::default(), &ctx.limits)
        .map(drop)
        .map_err(BackendError::Tuning)
}

/// The launch of `plan` on `ctx`: the environment's overrides over the
/// cached probe of this adapter and shape, probing (and caching) once
/// when there is none.
pub fn launch_for(
    ctx: &GpuContext,
    plan: &Plan,
    precision: Precision,
) -> Result<Launch, BackendError> {
    let env = Overrides::from_env().map_err(BackendError::Tuning)?;
    let launch = if env.complete() {
        Launch::default()
    } else {
        tuned(ctx, plan, precision, false)?.launch
    };
    env.apply(launch, &ctx.limits).map_err(BackendError::Tuning)
}

/// This adapter's probe of `plan`'s shape: from this process's memory, the
/// cache file, or measured now (`again`: measured now in any case).
pub fn tuned(
    ctx: &GpuContext,
    plan: &Plan,
    precision: Precision,
    again: bool,
) -> Result<Tuned, BackendError> {
    let (adapter, shape) = (adapter_key(&ctx.info), shape(ctx, plan, precision));
    // A run that finds another probing waits, then takes its result.
    let _probing = ctx.probing();
    if !again {
        if let Some(t) = ctx.tuned(&shape) {
            return Ok(t);
        }
        if let Some(t) = Cache::load()
            .get(&adapter, &shape)
            .filter(|t| t.launch.check(&ctx.limits).is_ok())
        {
            ctx.remember(&shape, t);
            return Ok(t.clone());
        }
    }
    let t = match precision {
        Precision::F32 => probe::<f32>(ctx, plan)?,
        Precision::F64 => probe::<f64>(ctx, plan)?,
    };
    if let Err(e) = Cache::store(&adapter, &shape, &t) {
        eprintln!("note: the GPU tuning could not be cached ({e}); it is measured again next time");
    }
    ctx.remember(&shape, &t);
    Ok(t)
}

/// Measures the candidate launches on the first trajectories of `plan`
/// (on a software adapter blocks of steps per finite test, then a
/// workgroup size, then trajectories per invocation), and the CPU.
fn probe<R: Flows>(ctx: &GpuContext, plan: &Plan) -> Result<Tuned, BackendError> {
    let started = Instant::now();
    let compiled = ctx.compile_seconds();
    // Seconds spent measuring: a driver's first compile of a candidate (a
    // cold shader cache) is not the probe's to budget.
    let measuring = || started.elapsed().as_secs_f64() - (ctx.compile_seconds() - compiled);
    let log = std::env::var_os(PROBE_LOG).is_some_and(|v| !v.is_empty());
    let m = probe_size(ctx, plan);
    let software = gpu::is_software(&ctx.info);
    // Only kernels without observers have blocks of steps.
    let blocks = gpu::codegen::generate(&sample(plan, m, 1), Precision::of::<R>())?.has_blocks();
    let first = Launch {
        finite_block: if blocks && !software {
            GPU_FINITE_BLOCK
        } else {
            1
        },
        ..Launch::default()
    };
    let steps = calibrate(m, |s| gpu_rate::<R>(ctx, plan, m, s, &first))?;
    if !software {
        // A GPU raises its clocks only while busy (an H200 idled at a sixth
        // of its clock): a longer run first, so the candidates are timed at
        // a run's clocks, not the idle ones.
        gpu_rate::<R>(ctx, plan, m, 5 * steps, &first)?;
    }
    let mut best = (first, 0.0);
    // `always`: measured even past the budget (the first launch, so that
    // the rate `auto` weighs is measured; a software adapter's blocks).
    let consider = |l: Launch, always: bool, best: &mut (Launch, f64)| {
        if l.check(&ctx.limits).is_err() || (!always && measuring() > PROBE_SECONDS) {
            return Ok::<(), BackendError>(());
        }
        let t = Instant::now();
        let rate = gpu_rate::<R>(ctx, plan, m, steps, &l)?;
        if log {
            eprintln!(
                "probe {}: {}: {rate:.4e} trajectory-steps/s ({m} × {steps} steps in {:.3} s)",
                Precision::of::<R>().name(),
                l.describe(),
                t.elapsed().as_secs_f64()
            );
        }
        if rate > best.1 {
            *best = (l, rate);
        }
        Ok(())
    };
    consider(first, true, &mut best)?;
    if blocks && software {
        for b in FINITE_BLOCKS {
            consider(
                Launch {
                    finite_block: b,
                    ..first
                },
                true,
                &mut best,
            )?;
        }
    }
    let measured = best.0.workgroup;
    for w in WORKGROUPS.into_iter().filter(|&w| w != measured) {
        consider(
            Launch {
                workgroup: w,
                ..best.0
            },
            false,
            &mut best,
        )?;
    }
    for p in PER_THREAD.into_iter().skip(1) {
        consider(
            Launch {
                per_thread: p,
                ..best.0
            },
            false,
            &mut best,
        )?;
    }
    best.0.dispatch_seconds = dispatch_seconds::<R>(ctx, plan, &best.0)?;
    let gpu_host = gpu_host::<R>(ctx, plan, m, &best.0)?;
    let cpu_m = m.min(1 << 16);
    let cpu_steps = calibrate(cpu_m, |s| cpu_rate::<R>(plan, cpu_m, s))?;
    Ok(Tuned {
        launch: best.0,
        gpu_rate: best.1,
        // The better of two: a shared machine only ever slows a run down.
        cpu_rate: cpu_rate::<R>(plan, cpu_m, cpu_steps)?
            .max(cpu_rate::<R>(plan, cpu_m, cpu_steps)?),
        trajectories: m as u64,
        probe_seconds: started.elapsed().as_secs_f64(),
        compile_seconds: ctx.compile_seconds() - compiled,
        gpu_host_per_trajectory: gpu_host,
        cpu_host_per_trajectory: cpu_host::<R>(plan, m)?,
    })
}

/// Wall seconds per trajectory that a one-step GPU run of `m` trajectories
/// with `launch` spends beyond its kernel: the better of two (the first
/// may still compile).
fn gpu_host<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    m: usize,
    launch: &Launch,
) -> Result<f64, BackendError> {
    let p = sample(plan, m, 1);
    least(2, || {
        let t = Instant::now();
        let r = gpu::run_with::<R>(ctx, &p, None, &with(launch))?;
        let beyond = t.elapsed().as_secs_f64() - r.phases.integration - r.phases.compile;
        Ok(beyond.max(0.0) / m as f64)
    })
}

/// The same for the CPU backend.
fn cpu_host<R: Flows>(plan: &Plan, m: usize) -> Result<f64, BackendError> {
    let p = sample(plan, m, 1);
    least(2, || {
        let t = Instant::now();
        let (_, phases) = cpu::resumable::<R>(&p, None, cpu::isa(), None)?;
        let beyond = t.elapsed().as_secs_f64() - phases.integration;
        Ok(beyond.max(0.0) / m as f64)
    })
}

/// The least of `k` measurements: a shared machine only ever slows one down.
fn least(
    k: usize,
    mut once: impl FnMut() -> Result<f64, BackendError>,
) -> Result<f64, BackendError> {
    (0..k).try_fold(f64::INFINITY, |best, _| Ok(best.min(once()?)))
}

/// The GPU options of a run with `launch`.
fn with(launch: &Launch) -> GpuOptions {
    GpuOptions {
        launch: Some(*launch),
        ..Default::default()
    }
}

/// Steps at which one measurement takes about [`MEASURE_SECONDS`]: from
/// a first run of 4 steps (its one-time costs make it slow), then from one
/// at the steps that suggests.
fn calibrate(
    m: usize,
    rate: impl Fn(u64) -> Result<f64, BackendError>,
) -> Result<u64, BackendError> {
    let mut steps = 4;
    for _ in 0..2 {
        steps = ((rate(steps)? * MEASURE_SECONDS / m as f64) as u64).clamp(4, MOST_STEPS);
    }
    Ok(steps)
}

/// `plan` narrowed to its first `m` trajectories and `steps` steps.
fn sample(plan: &Plan, m: usize, steps: u64) -> Plan {
    let mut p = plan.rows(0..m.min(plan.n));
    p.steps = steps.min(plan.steps).max(1);
    p
}

/// Trajectory-steps per second of `launch` (the integration alone).
fn gpu_rate<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    m: usize,
    steps: u64,
    launch: &Launch,
) -> Result<f64, BackendError> {
    let p = sample(plan, m, steps);
    let r = gpu::run_with::<R>(ctx, &p, None, &with(launch))?;
    Ok((p.n as u64 * p.steps) as f64 / r.phases.integration.max(1e-9))
}

fn cpu_rate<R: Flows>(plan: &Plan, m: usize, steps: u64) -> Result<f64, BackendError> {
    let p = sample(plan, m, steps);
    let (_, phases) = cpu::resumable::<R>(&p, None, cpu::isa(), None)?;
    Ok((p.n as u64 * p.steps) as f64 / phases.integration.max(1e-9))
}

/// The time a dispatch aims at: long enough that the fixed cost of one
/// (submission, wait, read-back; measured on a one-step window of one
/// workgroup) is below 1 % of it, and at most a quarter second (progress,
/// checkpoints and a stop request are honoured between dispatches).
fn dispatch_seconds<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    launch: &Launch,
) -> Result<f64, BackendError> {
    let p = sample(plan, launch.workgroup as usize, 1);
    let fixed = least(3, || {
        let t = Instant::now();
        gpu::run_with::<R>(ctx, &p, None, &with(launch))?;
        Ok(t.elapsed().as_secs_f64())
    })?;
    Ok((100.0 * fixed).clamp(0.02, 0.25))
}

/// `auto`'s one line: which backend runs a plan of `n` trajectories ×
/// `steps` steps, and the estimates that decided it.
pub fn auto_notice(
    adapter: &str,
    precision: Precision,
    t: &Tuned,
    (n, steps): (u64, u64),
) -> String {
    let (gpu, cpu) = t.whole_run_seconds(n, steps);
    let (on, other) = match gpu <= cpu {
        true => (format!("the GPU ({adapter})"), "the CPU"),
        false => ("the CPU".to_string(), "the GPU"),
    };
    let host = |per: f64| n as f64 * per;
    format!(
        "note: --backend auto: running on {on}: {n} trajectories × {steps} steps in {precision} would take about {gpu:.3} s on the GPU ({:.3e} trajectory-steps/s and {:.3} s of host work: tables, buffers, read-back) and {cpu:.3} s on the CPU ({:.3e} trajectory-steps/s and {:.3} s of set-up); writing and pictures, the same on either, aside (tuning probe of {} trajectories; --backend cpu or gpu to choose {other})",
        t.gpu_rate,
        host(t.gpu_host_per_trajectory),
        t.cpu_rate,
        host(t.cpu_host_per_trajectory),
        t.trajectories
    )
}
