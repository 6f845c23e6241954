//! Runs a plan's kernel: ensembles larger than the adapter's storage-binding
//! limit are split into chunks; a dispatch never exceeds the workgroup limit
//! per dimension; long horizons are cut into windows of steps whose length
//! adapts so each dispatch takes about the launch's `dispatch_seconds` (no
//! multi-second kernels, and progress to report). The launch (workgroup,
//! trajectories per invocation) is `GpuOptions::launch`, tuned per adapter
//! by `backend/tune.rs`.

use std::io::Read;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use super::codegen::{frame_width, generate, LOOP_ITERATIONS};
use super::context::{GpuContext, GpuError};
use super::time_table::{self, TimeTable};
use super::tuning::Launch;
use crate::backend::checkpoint::Checkpoints;
use crate::backend::error::BackendError;
use crate::backend::phases::{lap, Phases};
use crate::models::Flows;
use crate::num::precision::{handed_back, is_f32, Precision};
use crate::plan::observations::{frames_per_trajectory, Observations};
use crate::plan::slots;
use crate::plan::snapshot::{get_array, get_into, invalid, put, put_slice, Header};
use crate::plan::{ObsVar, Plan};

/// GPU memory a run may take (buffers of one chunk).
pub const MEMORY_BUDGET: u64 = 1 << 30;
/// Steps one dispatch may take: no window asks llvmpipe for more loop
/// iterations than it runs (`codegen::LOOP_ITERATIONS`).
pub const MAX_STEPS_PER_DISPATCH: u64 = LOOP_ITERATIONS;

/// Knobs of a GPU run; the defaults come from the adapter's limits.
#[derive(Debug, Clone, Default)]
pub struct GpuOptions {
    /// Largest chunk of trajectories resident at once.
    pub max_chunk: Option<u64>,
    /// Largest window of steps per dispatch.
    pub max_steps_per_dispatch: Option<u64>,
    /// The launch (default: [`Launch::default`]; the bits never depend on it).
    pub launch: Option<Launch>,
}

/// Observations of a GPU run, and how long the integration took.
pub struct GpuRun<R> {
    pub observations: Observations<R>,
    /// Set-up, shader compilation, read-back and the integration alone (the
    /// dispatches, by GPU timestamps when the adapter has them, else by wall
    /// clock around each dispatch).
    pub phases: Phases,
    pub timing: &'static str,
    pub chunks: usize,
    pub dispatches: u64,
    /// When this run had the device's queue: from a chunk's first
    /// submission until its results were staged for reading (host clock).
    pub busy: Vec<(Instant, Instant)>,
}

/// Keep in sync with `struct Uniforms` of `shaders/driver.wgsl` (field
/// order and types; `tests/suite/shaders.rs` checks the size against naga's layout).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniforms {
    base: u32,
    count: u32,
    cap: u32,
    step0: u32,
    nsteps: u32,
    frame0: u32,
    nframes: u32,
    _pad: u32,
}

/// Bytes of the uniform block the driver reads (checked against the WGSL).
pub const UNIFORMS_BYTES: usize = std::mem::size_of::<Uniforms>();

struct Buffers {
    uniform: wgpu::Buffer,
    state: wgpu::Buffer,
    table: wgpu::Buffer,
    status: wgpu::Buffer,
    aux_r: wgpu::Buffer,
    aux_u: wgpu::Buffer,
    traj: wgpu::Buffer,
    points: wgpu::Buffer,
    /// The window's shared time terms (16 bytes, unread, without them).
    tterms: wgpu::Buffer,
    staging: wgpu::Buffer,
}

fn storage(ctx: &GpuContext, label: &str, bytes: u64) -> wgpu::Buffer {
    let usage =
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    ctx.buffer(label, bytes.max(16).next_multiple_of(4), usage)
}

/// The kernel's input table in the working precision, converted from the
/// f64 values piece by piece, in parallel, straight into the buffer's
/// mapped memory: no intermediate array (10⁷ initial values are 40–80 MB).
fn table_buffer<R: Flows>(ctx: &GpuContext, values: &[f64]) -> Result<wgpu::Buffer, BackendError> {
    use rayon::prelude::*;
    const PIECE: usize = 1 << 14;
    let size = std::mem::size_of::<R>();
    let buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("table"),
        size: ((values.len() * size) as u64).max(16).next_multiple_of(4),
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: true,
    });
    // Each piece through a mapped range of its own (they never overlap;
    // their offsets are multiples of the mapping's alignment).
    values
        .par_chunks(PIECE)
        .enumerate()
        .try_for_each(|(k, v)| {
            let at = (k * PIECE * size) as u64;
            let mut view = buf
                .slice(at..at + (v.len() * size) as u64)
                .get_mapped_range_mut()
                .map_err(|e| GpuError::Runtime(format!("{e:?}")))?;
            let piece: Vec<R> = v.iter().map(|x| R::from_f64(*x)).collect();
            view.copy_from_slice(bytemuck::cast_slice(&piece));
            Ok::<(), BackendError>(())
        })?;
    buf.unmap();
    Ok(buf)
}

/// Reads `bytes` from the start of `src` through `staging`.
fn read<T: bytemuck::Pod>(
    ctx: &GpuContext,
    src: &wgpu::Buffer,
    staging: &wgpu::Buffer,
    bytes: u64,
) -> Result<Vec<T>, BackendError> {
    read_with(ctx, src, staging, bytes, |v: &[T]| v.to_vec())
}

/// [`read`], handing the mapped bytes to `with` instead of copying them
/// out first (a chunk's state or frames: up to gigabytes).
fn read_with<T: bytemuck::Pod, O>(
    ctx: &GpuContext,
    src: &wgpu::Buffer,
    staging: &wgpu::Buffer,
    bytes: u64,
    with: impl FnOnce(&[T]) -> O,
) -> Result<O, BackendError> {
    if bytes == 0 {
        return Ok(with(&[]));
    }
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(src, 0, staging, 0, bytes);
    let copied = ctx.queue.submit([enc.finish()]);
    with_mapped(ctx, staging, bytes, copied, with)
}

/// The errors the device reported since the last call, as one.
pub(super) fn check(ctx: &GpuContext) -> Result<(), BackendError> {
    let errors = ctx.take_errors();
    if errors.is_empty() {
        Ok(())
    } else {
        Err(GpuError::Runtime(errors.join("; ")).into())
    }
}

/// Runs `plan` on the GPU in precision `R`.
pub fn run<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    progress: Option<&AtomicU64>,
) -> Result<GpuRun<R>, BackendError> {
    run_with(ctx, plan, progress, &GpuOptions::default())
}

/// [`run`] with explicit chunk and window limits (tests use small ones to
/// exercise every boundary).
pub fn run_with<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    progress: Option<&AtomicU64>,
    opts: &GpuOptions,
) -> Result<GpuRun<R>, BackendError> {
    run_resumable(ctx, plan, progress, opts, None)
}

/// What a snapshot of a GPU run names its engine: the adapter and driver
/// decide the bits, the chunk capacity where the snapshot's buffers belong.
pub fn fingerprint<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    opts: &GpuOptions,
) -> Result<String, BackendError> {
    Ok(engine_name(ctx, Sizes::new::<R>(ctx, plan, opts)?.cap))
}

/// [`fingerprint`] for a chunk capacity `cap`.
fn engine_name(ctx: &GpuContext, cap: u64) -> String {
    let i = &ctx.info;
    format!(
        "gpu {} ({:?}, {} {}, chunks of {cap})",
        i.name, i.backend, i.driver, i.driver_info
    )
}

/// [`run_with`] with checkpoints: continues from `cp`'s snapshot if it has
/// one, and takes one between two windows whenever it is due.
pub fn run_resumable<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    progress: Option<&AtomicU64>,
    opts: &GpuOptions,
    cp: Option<&mut Checkpoints>,
) -> Result<GpuRun<R>, BackendError> {
    // Through non-generic twins, compiled in this crate only (see
    // `in_precision`).
    if is_f32::<R>() {
        handed_back(run_f32(ctx, plan, progress, opts, cp))
    } else {
        handed_back(run_f64(ctx, plan, progress, opts, cp))
    }
}

/// [`run_in`] in f32.
#[inline(never)]
fn run_f32(
    ctx: &GpuContext,
    plan: &Plan,
    progress: Option<&AtomicU64>,
    opts: &GpuOptions,
    cp: Option<&mut Checkpoints>,
) -> Result<GpuRun<f32>, BackendError> {
    run_in(ctx, plan, progress, opts, cp)
}

/// [`run_in`] in f64.
#[inline(never)]
fn run_f64(
    ctx: &GpuContext,
    plan: &Plan,
    progress: Option<&AtomicU64>,
    opts: &GpuOptions,
    cp: Option<&mut Checkpoints>,
) -> Result<GpuRun<f64>, BackendError> {
    run_in(ctx, plan, progress, opts, cp)
}

fn run_in<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    progress: Option<&AtomicU64>,
    opts: &GpuOptions,
    mut cp: Option<&mut Checkpoints>,
) -> Result<GpuRun<R>, BackendError> {
    let mut since = Instant::now();
    let mut phases = Phases::default();
    let precision = Precision::of::<R>();
    check_fits(ctx, plan, precision)?;
    let mut out = Observations::<R>::try_for_plan(plan).map_err(BackendError::TooLarge)?;
    if plan.n == 0 {
        return Ok(GpuRun {
            observations: out,
            phases,
            timing: "none",
            chunks: 0,
            dispatches: 0,
            busy: vec![],
        });
    }
    let mut sizes = Sizes::new::<R>(ctx, plan, opts)?;
    phases.setup += lap(&mut since);
    let kernel = generate(plan, precision)?;
    let pipeline = ctx.pipeline(&kernel.source_for(&sizes.launch, ctx.forms()))?;
    phases.compile = lap(&mut since);
    // llvmpipe's loop limit counts an invocation's trajectories together.
    sizes.max_window = sizes.max_window.min(match sizes.launch.per_thread as u64 {
        1 => kernel.max_window,
        per => (kernel.max_window / per).saturating_sub(1).max(1),
    });
    if let Some(tt) = &kernel.time_table {
        sizes.max_window = sizes.max_window.min(tt.max_steps(sizes.b));
    }
    let bufs = Buffers::new(
        ctx,
        &sizes,
        table_buffer::<R>(ctx, &kernel.table)?,
        kernel.time_table.is_some(),
    );
    let run = Dispatcher {
        ctx,
        plan,
        time_table: kernel.time_table.as_ref(),
        sizes: &sizes,
        bufs: &bufs,
        pipeline: &pipeline,
        bind: bind_group(ctx, &bufs),
        timestamps: Timestamps::new(ctx),
    };
    let mut header = Header::of::<R>(plan, engine_name(ctx, sizes.cap));
    // Where the first chunk starts: (its first trajectory, its first step).
    let mut start = (0u64, 0u64);
    if let Some(c) = cp.as_deref_mut() {
        (start, header.seconds) = run.resume(c, &mut out, progress)?;
    }
    let mut chunks = 0;
    let mut base = start.0;
    let mut totals = (header.seconds, 0u64);
    let mut busy = vec![];
    phases.setup += lap(&mut since);
    // Trajectory-steps per dispatch, adapted to the measured speed.
    let mut budget: f64 = 1e6;
    while base < plan.n as u64 {
        let count = sizes.cap.min(plan.n as u64 - base);
        let from = if base == start.0 { start.1 } else { 0 };
        chunks += 1;
        // Stopped (Ctrl-C, SIGTERM): the work so far is kept too, unless
        // the run takes no checkpoints.
        let mut between = |out: &Observations<R>, step0: u64, seconds: f64| {
            let Some(c) = cp.as_deref_mut() else {
                return Ok(());
            };
            let stopped = c.stopped();
            if c.due() || (stopped && c.every.is_some()) {
                let h = Header {
                    seconds: totals.0 + seconds,
                    traj_steps: base * plan.steps + count * step0,
                    ..header.clone()
                };
                run.checkpoint(c, &h, out, base, step0)?;
            }
            match stopped {
                true => Err(BackendError::Stopped),
                false => Ok(()),
            }
        };
        // The queue is this run's until the chunk's results are staged;
        // then another run's chunk integrates while this one reads back.
        let turn = ctx.queue_turn();
        let took = Instant::now();
        let (s, d, frames) = run.chunk(
            &mut out,
            base,
            count,
            from,
            &mut budget,
            progress,
            &mut between,
        )?;
        let staged = stage(ctx, &sizes, &bufs);
        drop(turn);
        busy.push((took, Instant::now()));
        totals = (totals.0 + s, totals.1 + d);
        lap(&mut since);
        collect(ctx, plan, &sizes, &bufs, &staged, &mut out, base, count)?;
        phases.read_back += frames + lap(&mut since);
        base += count;
    }
    phases.integration = totals.0;
    let timing = match run.timestamps {
        Some(_) => "GPU timestamps",
        None => "wall clock",
    };
    drop(run);
    bufs.give_back(ctx);
    Ok(GpuRun {
        observations: out,
        phases,
        timing,
        chunks,
        dispatches: totals.1,
        busy,
    })
}

/// Refuses what the adapter cannot run: f64 without f64 shaders, counts
/// beyond the kernel's 32-bit indices.
fn check_fits(ctx: &GpuContext, plan: &Plan, precision: Precision) -> Result<(), BackendError> {
    if precision == Precision::F64 && !ctx.shader_f64 {
        return Err(GpuError::NoF64(ctx.describe()).into());
    }
    let rows = plan.first.saturating_add(plan.n);
    if rows > u32::MAX as usize || plan.steps > u32::MAX as u64 - 1 {
        return Err(BackendError::TooLarge(format!(
            "the GPU backend counts trajectories and steps in 32 bits: {} trajectories, {} steps",
            rows, plan.steps
        )));
    }
    Ok(())
}

/// Sizes of one chunk's buffers.
struct Sizes {
    /// Bytes of the precision.
    b: u64,
    /// Integrated variables, trajectory variables, Poincaré variables.
    nv: u64,
    tv: u64,
    pv: u64,
    max_points: u64,
    /// Trajectories resident at once (a multiple of the workgroup size).
    cap: u64,
    /// Most steps and trajectory frames one dispatch may take.
    max_window: u64,
    max_frames: u64,
    /// Steps between trajectory frames (0: no trajectory observer).
    every: u64,
    /// The attractor detector's samples without a section: every `.0`
    /// steps from step `.1` on, each at the end of a window.
    samples: Option<(u64, u64)>,
    /// Real observer slots per trajectory (`slots::real`).
    real_slots: u64,
    /// Whether the plan has observers whose slots the kernel keeps.
    observed: bool,
    launch: Launch,
}

impl Sizes {
    /// The chunk capacity from the per-trajectory size of every buffer,
    /// within the adapter's binding limit and reeb's memory budget, for a
    /// launch the adapter allows (refused before it is tried).
    fn new<R>(ctx: &GpuContext, plan: &Plan, opts: &GpuOptions) -> Result<Sizes, BackendError> {
        let launch = opts.launch.unwrap_or_default();
        launch.check(&ctx.limits).map_err(BackendError::Tuning)?;
        let wg = launch.workgroup as u64;
        let b = std::mem::size_of::<R>() as u64;
        let (nv, tv, pv) = (
            plan.vars.len() as u64,
            frame_width(plan) as u64,
            plan.poincare_vars.len() as u64,
        );
        let max_points = plan.observers.poincare.as_ref().map_or(0, |p| p.max_points) as u64;
        let limit = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size);
        // One trajectory's Poincaré points, checked (max_points is the
        // scene's, up to 2^63); the other per-trajectory sizes are small.
        let points = max_points
            .checked_mul(pv)
            .and_then(|x| x.checked_mul(b))
            .ok_or_else(|| {
                BackendError::TooLarge(format!(
                    "{max_points} Poincaré points × {pv} variables per trajectory do not fit in 64 bits: lower output.poincare.max_points"
                ))
            })?;
        let real_slots = slots::real(plan).len() as u64;
        let per_buffer = [
            nv * b,
            4,
            real_slots * b,
            slots::COUNT.len() as u64 * 4,
            points,
        ];
        let widest = *per_buffer.iter().max().expect("nonempty");
        // Saturating: a sum beyond 64 bits leaves no room in the budget.
        let per_trajectory = per_buffer.iter().fold(0u64, |a, x| a.saturating_add(*x));
        let mut cap = (plan.n as u64)
            .min(limit / widest)
            .min(MEMORY_BUDGET / per_trajectory);
        // Trajectory frames: at least two per window must fit.
        if tv > 0 {
            cap = cap.min(limit / (2 * tv * b));
        }
        if cap == 0 {
            return Err(BackendError::TooLarge(format!(
                "one trajectory's observations ({} bytes) exceed the adapter's storage binding limit ({limit} bytes): lower output.poincare.max_points or the number of recorded variables",
                widest
            )));
        }
        cap = cap
            .next_multiple_of(wg)
            .min(limit / widest / wg * wg)
            .max(wg.min(cap));
        if let Some(m) = opts.max_chunk {
            cap = cap.min(m.max(1));
        }
        // No more frames than the run records: wgpu clears each buffer
        // before its first use, so a frame buffer sized to the budget cost
        // a clear of up to 1 GiB per run (a third of a small run's time on
        // lavapipe).
        let recorded = frames_per_trajectory(plan).unwrap_or(u64::MAX);
        let max_frames = if tv > 0 {
            (limit / (cap * tv * b))
                .min(MEMORY_BUDGET / (cap * tv * b))
                .min(recorded)
                .max(2)
        } else {
            0
        };
        Ok(Sizes {
            b,
            nv,
            tv,
            pv,
            max_points,
            cap,
            max_window: opts
                .max_steps_per_dispatch
                .unwrap_or(MAX_STEPS_PER_DISPATCH)
                .min(launch.window.unwrap_or(MAX_STEPS_PER_DISPATCH))
                .clamp(1, MAX_STEPS_PER_DISPATCH),
            max_frames,
            every: plan.observers.trajectory.as_ref().map_or(0, |t| t.every),
            samples: match (&plan.observers.attractors, &plan.observers.poincare) {
                (Some(a), None) => Some((a.every(plan.steps), a.first_sample(plan.steps))),
                _ => None,
            },
            real_slots,
            observed: plan.has_slots(),
            launch,
        })
    }

    /// Bytes of the buffers that carry a chunk from one window to the next,
    /// in the order a snapshot holds them: state, status, aux_r, aux_u,
    /// points.
    fn carried(&self) -> [u64; 5] {
        let (b, cap) = (self.b, self.cap);
        [
            self.nv * cap * b,
            4 * cap,
            self.real_slots * cap * b,
            slots::COUNT.len() as u64 * cap * 4,
            self.max_points * self.pv * cap * b,
        ]
    }

    /// Where [`stage`] copies the carried buffers in the staging buffer:
    /// one after another, each at an offset aligned for any precision; the
    /// observers' slots and points (empty) only where the plan has some.
    fn staged(&self) -> [Range<u64>; 5] {
        let [state, status, aux_r, aux_u, points] = self.carried();
        let observed = |bytes: u64| if self.observed { bytes } else { 0 };
        let mut at = 0;
        [
            state,
            status,
            observed(aux_r),
            observed(aux_u),
            observed(points),
        ]
        .map(|bytes| {
            let r = at..at + bytes;
            at = r.end.next_multiple_of(256);
            r
        })
    }

    /// The window of steps from `step0` that a dispatch of `count`
    /// trajectories takes within `budget` trajectory-steps, and the
    /// trajectory frames it records: `(nsteps, frame0, nframes)`.
    fn window(&self, step0: u64, steps: u64, count: u64, budget: f64) -> (u64, u64, u64) {
        let mut nsteps = ((budget / count as f64) as u64)
            .clamp(1, steps - step0)
            .min(self.max_window);
        // Frames f with f·every in the window (step 0 itself on the first
        // window) go to traj_out; at most `max_frames` of them fit.
        if let Some((every, first)) = self.samples {
            // A window ends at each sample, which the kernel takes after
            // its step loop (`codegen.rs`, `window_sample`).
            let next = ((step0 / every + 1) * every).max(first);
            nsteps = nsteps.min(next.saturating_sub(step0)).max(1);
        }
        let (mut frame0, mut nframes) = (0, 0);
        if let Some(after) = step0.checked_div(self.every) {
            frame0 = if step0 == 0 { 0 } else { after + 1 };
            nsteps = nsteps
                .min((frame0 + self.max_frames) * self.every - 1 - step0)
                .max(1);
            nframes = ((step0 + nsteps) / self.every + 1).saturating_sub(frame0);
        }
        (nsteps, frame0, nframes)
    }
}

impl Buffers {
    fn new(ctx: &GpuContext, s: &Sizes, table: wgpu::Buffer, time_table: bool) -> Buffers {
        let (b, cap) = (s.b, s.cap);
        let frames = s.max_frames * s.tv * b * cap;
        let uniform = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let tterms = if time_table { time_table::BYTES } else { 16 };
        Buffers {
            uniform: ctx.buffer("uniforms", std::mem::size_of::<Uniforms>() as u64, uniform),
            state: storage(ctx, "state", s.nv * cap * b),
            table,
            status: storage(ctx, "status", 4 * cap),
            tterms: ctx.buffer("time terms", tterms, uniform),
            aux_r: storage(ctx, "aux_r", s.real_slots * cap * b),
            aux_u: storage(ctx, "aux_u", slots::COUNT.len() as u64 * cap * 4),
            traj: storage(ctx, "trajectory", frames),
            points: storage(ctx, "points", s.max_points * s.pv * cap * b),
            staging: ctx.buffer(
                "staging",
                s.carried()
                    .into_iter()
                    .chain([s.staged()[4].end, frames, 16])
                    .max()
                    .unwrap_or(16),
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
        }
    }

    /// The buffers that carry a chunk from one window to the next, in the
    /// order of [`Sizes::carried`].
    fn carried(&self) -> [&wgpu::Buffer; 5] {
        [
            &self.state,
            &self.status,
            &self.aux_r,
            &self.aux_u,
            &self.points,
        ]
    }

    /// Hands the buffers of a finished run to the context for the next
    /// (the table is the run's own).
    fn give_back(self, ctx: &GpuContext) {
        let kept = [
            self.uniform,
            self.state,
            self.status,
            self.aux_r,
            self.aux_u,
            self.traj,
            self.points,
            self.tterms,
            self.staging,
        ];
        kept.into_iter().for_each(|b| ctx.give_back(b));
    }
}

/// The kernel's bindings, in the order of `shaders/driver.wgsl`.
fn bind_group(ctx: &GpuContext, bufs: &Buffers) -> wgpu::BindGroup {
    let order = [
        &bufs.uniform,
        &bufs.state,
        &bufs.table,
        &bufs.status,
        &bufs.aux_r,
        &bufs.aux_u,
        &bufs.traj,
        &bufs.points,
        &bufs.tterms,
    ];
    let entries: Vec<wgpu::BindGroupEntry> = order
        .iter()
        .enumerate()
        .map(|(k, buf)| wgpu::BindGroupEntry {
            binding: k as u32,
            resource: buf.as_entire_binding(),
        })
        .collect();
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("reeb kernel"),
        layout: ctx.bind_group_layout(),
        entries: &entries,
    })
}

/// Timestamp queries around each dispatch, where the adapter has them.
struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    period_ns: f64,
}

impl Timestamps {
    fn new(ctx: &GpuContext) -> Option<Timestamps> {
        let buffer = |label, usage| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        ctx.timestamps.then(|| Timestamps {
            set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("dispatch"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: buffer(
                "timestamps",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: buffer(
                "timestamps readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            period_ns: ctx.queue.get_timestamp_period() as f64,
        })
    }
}

/// Runs windows of the kernel over a chunk.
struct Dispatcher<'a> {
    ctx: &'a GpuContext,
    plan: &'a Plan,
    time_table: Option<&'a TimeTable>,
    sizes: &'a Sizes,
    bufs: &'a Buffers,
    pipeline: &'a wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    timestamps: Option<Timestamps>,
}

/// Called between two windows of a chunk with the observations, the next
/// window's first step and the chunk's integration seconds so far.
type Between<'b, R> = &'b mut dyn FnMut(&Observations<R>, u64, f64) -> Result<(), BackendError>;

impl Dispatcher<'_> {
    /// Integrates trajectories `base..base+count` from step `from` (0, or
    /// where a snapshot left them) to the horizon, window by window, reading
    /// the trajectory frames back as they come; returns the integration
    /// seconds, the number of dispatches and the seconds reading frames.
    #[allow(clippy::too_many_arguments)]
    fn chunk<R: Flows>(
        &self,
        out: &mut Observations<R>,
        base: u64,
        count: u64,
        from: u64,
        budget: &mut f64,
        progress: Option<&AtomicU64>,
        between: Between<R>,
    ) -> Result<(f64, u64, f64), BackendError> {
        let (ctx, plan, sizes, bufs) = (self.ctx, self.plan, self.sizes, self.bufs);
        if from == 0 {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            enc.clear_buffer(&bufs.status, 0, None);
            ctx.queue.submit([enc.finish()]);
        }
        let (mut seconds, mut dispatches, mut frames) = (0.0, 0, 0.0);
        let mut step0 = from;
        while step0 < plan.steps {
            if step0 > from {
                between(out, step0, seconds)?;
            }
            let (nsteps, frame0, nframes) = sizes.window(step0, plan.steps, count, *budget);
            let u = Uniforms {
                base: (plan.first as u64 + base) as u32,
                count: count as u32,
                cap: sizes.cap as u32,
                step0: step0 as u32,
                nsteps: nsteps as u32,
                frame0: frame0 as u32,
                nframes: nframes as u32,
                _pad: 0,
            };
            if let Some(tt) = self.time_table {
                let rows = tt.fill::<R>(plan, step0, nsteps);
                ctx.queue
                    .write_buffer(&bufs.tterms, 0, bytemuck::cast_slice(&rows));
            }
            let (wall, took) = self.dispatch(&u, count)?;
            seconds += took;
            dispatches += 1;
            if nframes > 0 {
                let read = Instant::now();
                read_frames(ctx, plan, sizes, bufs, out, base, count, frame0, nframes)?;
                frames += read.elapsed().as_secs_f64();
            }
            if let Some(p) = progress {
                p.fetch_add(count * nsteps, Ordering::Relaxed);
            }
            // Aim at the target time per dispatch, changing by at most 4× at once.
            let rate = (count * nsteps) as f64 / wall.max(1e-6);
            *budget = (rate * sizes.launch.dispatch_seconds)
                .clamp(*budget / 4.0, *budget * 4.0)
                .max(count as f64);
            step0 += nsteps;
        }
        Ok((seconds, dispatches, frames))
    }

    /// The buffers that carry a chunk from one window to the next, in the
    /// order a snapshot holds them, with their sizes in bytes.
    fn carried(&self) -> [(&wgpu::Buffer, u64); 5] {
        let (bufs, bytes) = (self.bufs.carried(), self.sizes.carried());
        std::array::from_fn(|k| (bufs[k], bytes[k]))
    }

    /// Saves a snapshot of the chunk at `base` before step `step0`.
    fn checkpoint<R: Flows>(
        &self,
        cp: &mut Checkpoints,
        header: &Header,
        out: &Observations<R>,
        base: u64,
        step0: u64,
    ) -> Result<(), BackendError> {
        let carried = self
            .carried()
            .into_iter()
            .map(|(buf, bytes)| read::<u8>(self.ctx, buf, &self.bufs.staging, bytes))
            .collect::<Result<Vec<_>, _>>()?;
        cp.take(header, out, &|w| {
            put(w, &[base, step0])?;
            carried.iter().try_for_each(|c| put_slice(w, c))
        })
        .map_err(BackendError::checkpoint)
    }

    /// Continues from `cp`'s snapshot, if it has one: its observations into
    /// `out`, its buffers loaded, its trajectory-steps counted. Returns where
    /// the first chunk starts (trajectory, step) and the seconds before.
    fn resume<R: Flows>(
        &self,
        cp: &mut Checkpoints,
        out: &mut Observations<R>,
        progress: Option<&AtomicU64>,
    ) -> Result<((u64, u64), f64), BackendError> {
        let Some((h, r)) = cp.restore(out).map_err(BackendError::checkpoint)? else {
            return Ok(((0, 0), 0.0));
        };
        let start = self.restore(r).map_err(BackendError::checkpoint)?;
        if let Some(p) = progress {
            p.fetch_add(h.traj_steps, Ordering::Relaxed);
        }
        Ok((start, h.seconds))
    }

    /// Loads the buffers of a snapshot's chunk; returns its first trajectory
    /// and the step it continues from.
    fn restore(&self, r: &mut dyn Read) -> std::io::Result<(u64, u64)> {
        let [base, step0]: [u64; 2] = get_array(r)?;
        let (n, steps) = (self.plan.n as u64, self.plan.steps);
        if base >= n || base % self.sizes.cap != 0 || step0 == 0 || step0 >= steps {
            return Err(invalid(&format!(
                "a chunk at trajectory {base}, step {step0}"
            )));
        }
        for (buf, bytes) in self.carried() {
            let mut v = vec![0u8; bytes as usize];
            get_into(r, &mut v)?;
            if bytes > 0 {
                self.ctx.queue.write_buffer(buf, 0, &v);
            }
        }
        Ok((base, step0))
    }

    /// One dispatch with uniforms `u`; returns (wall seconds, integration
    /// seconds by timestamps where available).
    fn dispatch(&self, u: &Uniforms, count: u64) -> Result<(f64, f64), BackendError> {
        let (ctx, bufs) = (self.ctx, self.bufs);
        ctx.queue
            .write_buffer(&bufs.uniform, 0, bytemuck::bytes_of(u));
        let launch = &self.sizes.launch;
        let threads = count.div_ceil(launch.per_thread as u64);
        let groups = threads.div_ceil(launch.workgroup as u64);
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension as u64;
        let gx = groups.min(max_dim);
        let gy = groups.div_ceil(gx);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("reeb window"),
                timestamp_writes: self.timestamps.as_ref().map(|t| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: &t.set,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }
                }),
            });
            pass.set_pipeline(self.pipeline);
            pass.set_bind_group(0, &self.bind, &[]);
            pass.dispatch_workgroups(gx as u32, gy as u32, 1);
        }
        if let Some(t) = &self.timestamps {
            enc.resolve_query_set(&t.set, 0..2, &t.resolve, 0);
            enc.copy_buffer_to_buffer(&t.resolve, 0, &t.readback, 0, 16);
        }
        let started = Instant::now();
        let submitted = ctx.queue.submit([enc.finish()]);
        wait_for(ctx, submitted.clone())?;
        let wall = started.elapsed().as_secs_f64();
        check(ctx)?;
        let took = match &self.timestamps {
            Some(t) => {
                let ts: Vec<u64> = read_mapped(ctx, &t.readback, 16, submitted)?;
                let gpu = ts[1].saturating_sub(ts[0]) as f64 * t.period_ns * 1e-9;
                if gpu > 0.0 {
                    gpu
                } else {
                    wall
                }
            }
            None => wall,
        };
        Ok((wall, took))
    }
}

/// Copies the trajectory frames `frame0..frame0+nframes` of a window into
/// the observations.
#[allow(clippy::too_many_arguments)]
fn read_frames<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    s: &Sizes,
    bufs: &Buffers,
    out: &mut Observations<R>,
    base: u64,
    count: u64,
    frame0: u64,
    nframes: u64,
) -> Result<(), BackendError> {
    let bytes = nframes * s.tv * s.cap * s.b;
    read_with(ctx, &bufs.traj, &bufs.staging, bytes, |frames: &[R]| {
        place_frames(plan, s, out, frames, (base, count), (frame0, nframes))
    })
}

/// [`read_frames`]' frames (frame-major, then variable, then trajectory)
/// in the observations: trajectory by trajectory in parallel, then the
/// indicators' running values.
fn place_frames<R: Flows>(
    plan: &Plan,
    s: &Sizes,
    out: &mut Observations<R>,
    frames: &[R],
    (base, count): (u64, u64),
    (frame0, nframes): (u64, u64),
) {
    use rayon::prelude::*;
    let (tv, cap) = (s.tv, s.cap);
    let frames_total = out.frames;
    let at = |f: u64, j: usize, i: u64| frames[((f * tv + j as u64) * cap + i) as usize];
    for (j, (_, dst)) in out.trajectory.iter_mut().enumerate() {
        let rows = base as usize * frames_total..(base + count) as usize * frames_total;
        dst[rows]
            .par_chunks_mut(frames_total)
            .enumerate()
            .for_each(|(i, orbit)| {
                for f in 0..nframes {
                    orbit[(frame0 + f) as usize] = at(f, j, i as u64);
                }
            });
    }
    if plan.indicators.is_none() {
        return;
    }
    // The indicators' slots of each frame make their running values, as
    // the CPU makes them from its own slots.
    let recorded = slots::indicator_frame_slots(plan);
    let first = plan.trajectory_vars.len();
    let every = plan.observers.trajectory.as_ref().map_or(1, |t| t.every);
    for i in 0..count {
        let g = (base + i) as usize;
        let dt = lane_dt::<R>(plan, g);
        for f in 0..nframes {
            let slot = |k: usize| {
                let m = recorded.iter().position(|r| *r == k);
                m.map_or(R::nan(), |m| at(f, first + m, i))
            };
            let frame = frame0 + f;
            let values = slots::indicators_at(plan, slot, dt, true, frame * every);
            let row = g * out.frames + frame as usize;
            let (lyapunov, scalars) = out.indicators_mut(true);
            values.put(lyapunov, scalars, row);
        }
    }
}

/// Trajectory `g`'s step in the working precision.
fn lane_dt<R: Flows>(plan: &Plan, g: usize) -> R {
    R::from_f64(plan.binding("dt").value_at(plan.first + g, &plan.strides))
}

/// Waits until the work of submission `index` has finished (not for later
/// submissions: another run's dispatches on the same device).
fn wait_for(ctx: &GpuContext, index: wgpu::SubmissionIndex) -> Result<(), BackendError> {
    let wait = wgpu::PollType::Wait {
        submission_index: Some(index),
        timeout: None,
    };
    ctx.device
        .poll(wait)
        .map_err(|e| GpuError::Runtime(e.to_string()))?;
    Ok(())
}

/// Maps a small MAP_READ buffer, written by submission `after`, and
/// returns its contents.
pub(super) fn read_mapped<T: bytemuck::Pod>(
    ctx: &GpuContext,
    buf: &wgpu::Buffer,
    bytes: u64,
    after: wgpu::SubmissionIndex,
) -> Result<Vec<T>, BackendError> {
    with_mapped(ctx, buf, bytes, after, |v: &[T]| v.to_vec())
}

/// Maps a MAP_READ buffer once submission `after` (which wrote it) has
/// finished, and hands its contents to `with`.
fn with_mapped<T: bytemuck::Pod, O>(
    ctx: &GpuContext,
    buf: &wgpu::Buffer,
    bytes: u64,
    after: wgpu::SubmissionIndex,
    with: impl FnOnce(&[T]) -> O,
) -> Result<O, BackendError> {
    let slice = buf.slice(..bytes);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    wait_for(ctx, after)?;
    // The mapping is resolved by that wait; should it not be yet, by
    // waiting for all the device's work.
    let mapped = match rx.try_recv() {
        Ok(r) => r,
        Err(_) => {
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Runtime(e.to_string()))?;
            rx.recv().map_err(|e| GpuError::Runtime(e.to_string()))?
        }
    };
    mapped.map_err(|e| GpuError::Runtime(e.to_string()))?;
    let out = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Runtime(format!("{e:?}")))?;
        with(bytemuck::cast_slice::<u8, T>(&view))
    };
    buf.unmap();
    Ok(out)
}

/// A finished chunk's results in the staging buffer: where each carried
/// buffer lies ([`Sizes::staged`]), and the submission that copies them.
struct Staged {
    ranges: [Range<u64>; 5],
    copied: wgpu::SubmissionIndex,
}

/// Copies a finished chunk's results into the staging buffer in one
/// submission, made while the run still has the queue: reading them back
/// then waits for this copy alone, not for another run's dispatches after it.
fn stage(ctx: &GpuContext, s: &Sizes, bufs: &Buffers) -> Staged {
    let ranges = s.staged();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    for (src, r) in bufs.carried().into_iter().zip(&ranges) {
        if r.end > r.start {
            enc.copy_buffer_to_buffer(src, 0, &bufs.staging, r.start, r.end - r.start);
        }
    }
    let copied = ctx.queue.submit([enc.finish()]);
    Staged { ranges, copied }
}

/// A chunk's results as the kernel left them: `cap` rows per variable or
/// slot, `status` cut to the chunk's trajectories.
struct Results<'a, R> {
    cap: u64,
    status: &'a [u32],
    state: &'a [R],
    aux_r: &'a [R],
    aux_u: &'a [u32],
    points: &'a [R],
}

/// Reads a finished chunk's staged results into the observations (rows
/// `base..base+count`).
#[allow(clippy::too_many_arguments)]
fn collect<R: Flows>(
    ctx: &GpuContext,
    plan: &Plan,
    s: &Sizes,
    bufs: &Buffers,
    staged: &Staged,
    out: &mut Observations<R>,
    base: u64,
    count: u64,
) -> Result<(), BackendError> {
    let [state, status, aux_r, aux_u, points] = staged.ranges.clone();
    let end = points.end;
    with_mapped(
        ctx,
        &bufs.staging,
        end,
        staged.copied.clone(),
        |bytes: &[u8]| {
            let part = |r: &Range<u64>| &bytes[r.start as usize..r.end as usize];
            let status: &[u32] = bytemuck::cast_slice(part(&status));
            let status = &status[..count as usize];
            let cut = status.iter().filter(|s| **s == slots::CUT).count();
            if cut > 0 {
                return Err(BackendError::Cut(format!(
                "the adapter ended the kernel's step loop early in {cut} of {count} trajectories (a driver's limit on loop iterations, such as llvmpipe's {LOOP_ITERATIONS} per dispatch, which reeb's windows should respect: please report it); the CPU backend runs this scene"
            )));
            }
            let res = Results {
                cap: s.cap,
                status,
                state: bytemuck::cast_slice(part(&state)),
                aux_r: bytemuck::cast_slice(part(&aux_r)),
                aux_u: bytemuck::cast_slice(part(&aux_u)),
                points: bytemuck::cast_slice(part(&points)),
            };
            scatter(plan, res.state, status, out, base, s.cap);
            if plan.has_slots() {
                collect_observers(plan, &res, out, base);
            }
            Ok(())
        },
    )??;
    check(ctx)
}

/// The status, final values and frames of trajectories `base..` from a
/// chunk's state (`cap` rows per variable) and status words, in parallel.
fn scatter<R: Flows>(
    plan: &Plan,
    state: &[R],
    status: &[u32],
    out: &mut Observations<R>,
    base: u64,
    cap: u64,
) {
    use rayon::prelude::*;
    let rows = base as usize..base as usize + status.len();
    let split: Vec<(u32, u32)> = status
        .par_iter()
        .map(|s| slots::split_status((*s).into()))
        .collect();
    out.nonfinite_step[rows.clone()]
        .par_iter_mut()
        .zip(&mut out.stop_step[rows.clone()])
        .zip(&split)
        .for_each(|((nonfinite, stop), s)| (*nonfinite, *stop) = *s);
    for (j, v) in plan.final_vars.iter().enumerate() {
        let column = &mut out.final_values[j].1[rows.clone()];
        column.par_iter_mut().enumerate().for_each(|(i, dst)| {
            let (nonfinite, stop) = split[i];
            *dst = match (nonfinite, v) {
                (0, ObsVar::State(k)) => state[(*k as u64 * cap + i as u64) as usize],
                (0, ObsVar::Time) => time_at(plan, rows.start + i, slots::last_step(plan, stop)),
                _ => R::nan(),
            };
        });
    }
    let every = plan.observers.trajectory.as_ref().map_or(0, |t| t.every);
    if every == 0 {
        return;
    }
    // Frames recorded at or after the step where it became non-finite, or
    // after the one it stopped at, are NaN (as on the CPU).
    let first_nan = |(nonfinite, stop): (u32, u32)| match (nonfinite, stop) {
        (0, 0) => None,
        (0, stop) => Some(u64::from(stop) / every + 1),
        (k, _) => Some(u64::from(k).div_ceil(every)),
    };
    let frames = out.frames;
    for (dst, width) in out.framed_columns_mut() {
        if dst.is_empty() {
            continue;
        }
        let per = frames * width;
        dst[rows.start * per..rows.end * per]
            .par_chunks_mut(per)
            .zip(&split)
            .for_each(|(orbit, s)| {
                if let Some(first) = first_nan(*s) {
                    orbit[first as usize * width..].fill(R::nan());
                }
            });
    }
}

/// `t0 + steps·dt` of trajectory `g`, in the working precision.
fn time_at<R: Flows>(plan: &Plan, g: usize, steps: u64) -> R {
    let t0 = R::from_f64(plan.binding("t0").value_at(plan.first + g, &plan.strides));
    t0 + R::from_f64(steps as f64) * lane_dt::<R>(plan, g)
}

/// Poincaré points, cycle statistics and time averages of a finished chunk, from the
/// observer state the kernel kept (`plan/slots.rs`).
fn collect_observers<R: Flows>(
    plan: &Plan,
    res: &Results<R>,
    out: &mut Observations<R>,
    base: u64,
) {
    let cap = res.cap;
    let pv = plan.poincare_vars.len() as u64;
    let mp = out.max_points as u64;
    let detector = slots::recurrence(plan);
    for (i, &status) in res.status.iter().enumerate() {
        let (g, i) = (base as usize + i, i as u64);
        let slot = |k: usize| res.aux_r[(k as u64 * cap + i) as usize];
        if plan.observers.poincare.is_some() {
            let n = res.aux_u[(slots::NPOINTS as u64 * cap + i) as usize];
            out.poincare_count[g] = n;
            for k in 0..(n as u64).min(mp) {
                for j in 0..pv {
                    out.poincare[j as usize].1[g * mp as usize + k as usize] =
                        res.points[((k * pv + j) * cap + i) as usize];
                }
            }
        }
        let (nonfinite, stop) = slots::split_status(status.into());
        let ok = nonfinite == 0;
        if plan.cycle_var.is_some() {
            let (amplitude, period) = slots::cycle_finish(slot, ok);
            out.cycle_amplitude[g] = amplitude;
            out.cycle_period[g] = period;
        }
        for (j, (_, mean)) in out.mean.iter_mut().enumerate() {
            mean[g] = slots::mean_finish(plan, slot(slots::MEAN0 + j), ok, stop);
        }
        if plan.indicators.is_some() {
            let values = slots::indicators_finish(plan, slot, lane_dt::<R>(plan, g), ok, stop);
            let (lyapunov, scalars) = out.indicators_mut(false);
            values.put(lyapunov, scalars, g);
        }
        if let Some(at) = &detector {
            let end = slots::attractor_finish(at, slot, (nonfinite, stop));
            let points = out.attractor_points.iter_mut().map(|(_, v)| v).collect();
            end.put(&mut out.attractor_period, &mut out.transient, points, g);
        }
    }
}
