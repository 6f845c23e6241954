//! The adapter's f32 `exp` measured against f64's: the kernels' `exp_r`
//! evaluated on the device over a sweep of arguments (`reeb doctor`, the
//! tests; the f64 `log_r` too, for the tests). The hardware form's error
//! is the driver's exp2's plus under one ULP, and nothing but running it
//! says what the driver's is.

use super::codegen::{math_source, ExpForm, Forms};
use super::context::{GpuContext, GpuError};
use super::run::{check, read_mapped};
use crate::backend::error::BackendError;
use crate::num::precision::Precision;

/// The largest error of one form of the f32 `exp` on a device.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ExpAccuracy {
    pub form: ExpForm,
    /// Arguments evaluated.
    pub points: usize,
    /// Largest distance from f64's exp, in ULPs of the f32 result, where
    /// that is a normal f32.
    pub max_ulp: f64,
    /// The argument where it is largest.
    pub at: f32,
}

/// The arguments: evenly over [−87.3, 88.37] (exp's normal range, to where
/// reeb's polynomial's scale 2¹²⁸ overflows), and over
/// [−1, 1], where the integrators' damping factors e^{τ…} mostly lie, and
/// a few past overflow, in (88.73, 100], where exp is +∞.
pub fn arguments(n: usize) -> Vec<f32> {
    let even =
        |lo: f64, hi: f64, k: usize| (0..k).map(move |i| lo + (hi - lo) * i as f64 / k as f64);
    let over = 64.min(n / 4);
    even(-87.3, 88.37, n / 2)
        .chain(even(-1.0, 1.0, n - n / 2 - over))
        .chain(even(100.0, 88.73, over))
        .map(|x| x as f32)
        .collect()
}

/// `exp_r` in `form` of each of `xs`, on `ctx`.
pub fn exp_f32_on(ctx: &GpuContext, form: ExpForm, xs: &[f32]) -> Result<Vec<f32>, BackendError> {
    let forms = Forms {
        int64: ctx.shader_int64,
        exp: form,
    };
    evaluate(ctx, Precision::F32, forms, "exp_r", xs)
}

/// The f32 `name` (`log_r` or the indicators' `sample_log_r`) of each of
/// `xs`, on `ctx`.
pub fn log_f32_on(ctx: &GpuContext, name: &str, xs: &[f32]) -> Result<Vec<f32>, BackendError> {
    let forms = Forms {
        int64: ctx.shader_int64,
        exp: ExpForm::Exact,
    };
    evaluate(ctx, Precision::F32, forms, name, xs)
}

/// The f64 `name` (`log_r` or the indicators' `sample_log_r`) of each of
/// `xs`, on `ctx` (needs SHADER_F64), the split of x = 2^e·m from the bits
/// where `int64` (and the adapter has SHADER_INT64), else by the ladder of
/// scalings.
pub fn log_f64_on(
    ctx: &GpuContext,
    name: &str,
    int64: bool,
    xs: &[f64],
) -> Result<Vec<f64>, BackendError> {
    let forms = Forms {
        int64: int64 && ctx.shader_int64,
        exp: ExpForm::Exact,
    };
    evaluate(ctx, Precision::F64, forms, name, xs)
}

/// The kernels' one-argument function `name` of each of `xs` (of the
/// working type of `precision`) in `forms`, on `ctx`.
fn evaluate<T: bytemuck::Pod>(
    ctx: &GpuContext,
    precision: Precision,
    forms: Forms,
    name: &str,
    xs: &[T],
) -> Result<Vec<T>, BackendError> {
    if xs.is_empty() {
        return Ok(vec![]);
    }
    let source = format!(
        "{}\n@group(0) @binding(0) var<storage, read> xs: array<R>;
@group(0) @binding(1) var<storage, read_write> ys: array<R>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {{
    let i = id.y * nwg.x * 64u + id.x;
    if i < arrayLength(&xs) {{
        ys[i] = {name}(xs[i]);
    }}
}}",
        math_source(precision, forms)?,
    );
    super::validate(&source, precision == Precision::F64).map_err(GpuError::Shader)?;
    let pipeline = ctx.compile(&source, None, "reeb function check")?;
    let bytes = std::mem::size_of_val(xs) as u64;
    let buffer = |usage: wgpu::BufferUsages| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("reeb function check"),
            size: bytes.max(4),
            usage,
            mapped_at_creation: false,
        })
    };
    use wgpu::BufferUsages as U;
    let input = buffer(U::STORAGE | U::COPY_DST);
    let output = buffer(U::STORAGE | U::COPY_SRC);
    let staging = buffer(U::MAP_READ | U::COPY_DST);
    ctx.queue.write_buffer(&input, 0, bytemuck::cast_slice(xs));
    let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("reeb function check"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let groups = xs.len().div_ceil(64) as u32;
    let width = groups.min(ctx.limits.max_compute_workgroups_per_dimension);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(width, groups.div_ceil(width), 1);
    }
    enc.copy_buffer_to_buffer(&output, 0, &staging, 0, bytes);
    let submitted = ctx.queue.submit([enc.finish()]);
    let ys = read_mapped(ctx, &staging, bytes, submitted)?;
    check(ctx)?;
    Ok(ys)
}

/// The largest error of `form` on `ctx` over `n` arguments ([`arguments`]).
pub fn exp_f32_accuracy(
    ctx: &GpuContext,
    form: ExpForm,
    n: usize,
) -> Result<ExpAccuracy, BackendError> {
    let xs = arguments(n);
    let ys = exp_f32_on(ctx, form, &xs)?;
    let mut worst = ExpAccuracy {
        form,
        points: xs.len(),
        max_ulp: 0.0,
        at: 0.0,
    };
    for (&x, &y) in xs.iter().zip(&ys) {
        let exact = (x as f64).exp();
        let rounded = exact as f32;
        // Past overflow only +∞ is right.
        if rounded.is_infinite() && y != f32::INFINITY {
            (worst.max_ulp, worst.at) = (f64::INFINITY, x);
        }
        if !rounded.is_normal() {
            continue;
        }
        // The spacing of f32 at the exact value: 2^(its exponent − 23).
        let scale = f32::from_bits(rounded.to_bits() & 0x7f80_0000) as f64;
        let ulp = scale * f32::EPSILON as f64;
        let e = ((y as f64) - exact).abs() / ulp;
        // NaN (a wrong result that is not a number) counts as infinitely far.
        let e = if e.is_nan() { f64::INFINITY } else { e };
        if e > worst.max_ulp {
            (worst.max_ulp, worst.at) = (e, x);
        }
    }
    Ok(worst)
}

/// The most error the hardware exp may have where reeb takes it by default.
pub const HARDWARE_EXP_ULP: f64 = 4.0;

/// Keeps the hardware exp that a device took by default (not by
/// `REEB_GPU_EXP`) only where it measures within [`HARDWARE_EXP_ULP`]
/// over 2¹⁶ arguments (one small kernel, once per device); otherwise
/// reeb's polynomial, with a note. WGSL lets exp2 be off by 3 + 2|x| ULP,
/// so a driver's is not trusted unmeasured.
pub fn settle_exp(ctx: &mut GpuContext) {
    if ctx.exp_f32 != ExpForm::Hardware || super::context::exp_chosen() {
        return;
    }
    let why = match exp_f32_accuracy(ctx, ExpForm::Hardware, 1 << 16) {
        Ok(a) if a.max_ulp <= HARDWARE_EXP_ULP => return,
        Ok(a) => format!("is {:.1} ULP off at x = {}", a.max_ulp, a.at),
        Err(e) => format!("could not be measured ({e})"),
    };
    eprintln!(
        "note: the f32 exp from this adapter's exp2 {why}: reeb's polynomial instead (REEB_GPU_EXP=hardware to take it anyway)"
    );
    ctx.exp_f32 = ExpForm::Exact;
}
