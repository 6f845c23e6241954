//! The chaos indicators' sample programs compiled: for the usual shapes
//! (`plan/indicators.rs`'s [`SampleShape`], tangent dimensions 2 to 4)
//! `sample_ops.rs` holds each program as one lane loop, generated from the
//! same lowered program the tape and WGSL run and with the same functions:
//! the tape's operations, its bits where the compiler fuses no a·b + c
//! into an FMA. Other shapes keep the tape.

use super::sample_ops::{self, SHAPES};
use crate::models::lanes::LANES;
use crate::num::isa::Isa;
use crate::num::precision::{in_precision, Real};
use crate::plan::indicators::SampleShape;

/// One sample over a block: `(shape, arrays)`, pointers to the program's
/// inputs in its order, each one array of lanes; output k is written over
/// input k (the programs keep their state in that order: the vectors, then
/// the sums). Pointers, not one slice: a run of steps hands the deviation
/// vectors where they lie, in the compiled tangent's scratch lanes (their
/// copies in and out cost the full spectrum of a 2-D system 7 % of its
/// run). The flag: the sample is the skip step's (see
/// [`sample_ops::run`]). Unsafe to call: the AVX2/FMA and AVX-512
/// variants need those features, and the arrays must be as
/// [`sample_ops::run`] says.
pub type SampleFn<R> = unsafe fn(SampleShape, &[*mut [R; LANES]], bool);

/// Pointers to the arrays `x`, one after the other, in the first
/// `x.len()` places (from one base pointer, so that none invalidates
/// another).
#[inline(always)]
pub fn array_ptrs<R>(x: &mut [[R; LANES]]) -> [*mut [R; LANES]; sample_ops::MOST_ARRAYS] {
    let mut at = [std::ptr::null_mut(); sample_ops::MOST_ARRAYS];
    let base = x.as_mut_ptr();
    for (a, p) in at.iter_mut().enumerate().take(x.len()) {
        // SAFETY: `a` is below `x.len()`.
        *p = unsafe { base.add(a) };
    }
    at
}

/// Runs `f` on the arrays `x`, one after the other (`skip`: see
/// [`SampleFn`]).
///
/// # Safety
/// `f` must be one this CPU runs (see [`SampleFn`]).
#[inline(always)]
pub unsafe fn on_arrays<R: Real>(
    f: SampleFn<R>,
    shape: SampleShape,
    x: &mut [[R; LANES]],
    skip: bool,
) {
    let n = x.len();
    // SAFETY: distinct arrays of `x`, which this call borrows.
    unsafe { f(shape, &array_ptrs(x)[..n], skip) }
}

/// The sample program of `shape` compiled at level `isa`, if it is one of
/// the compiled shapes and the level is AVX2 or AVX-512 (as for the
/// compiled tangent: older CPUs keep the tape, and the build stays light).
pub fn sample_fn<R: Real>(shape: SampleShape, isa: Isa) -> Option<SampleFn<R>> {
    if !SHAPES.contains(&shape) {
        return None;
    }
    in_precision::<R, Option<SampleFn<R>>, _, _>(|| pick_f32(isa), || pick_f64(isa))
}

#[inline(never)]
fn pick_f32(isa: Isa) -> Option<SampleFn<f32>> {
    pick::<f32>(isa)
}

#[inline(never)]
fn pick_f64(isa: Isa) -> Option<SampleFn<f64>> {
    pick::<f64>(isa)
}

#[inline(always)]
fn pick<R: Real>(isa: Isa) -> Option<SampleFn<R>> {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::V4 => return Some(sample_v4::<R>),
        Isa::V3 => return Some(sample_v3::<R>),
        Isa::Baseline => {}
    }
    let _ = isa;
    None
}

/// [`sample_ops::run`] compiled for AVX2 and FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn sample_v3<R: Real>(s: SampleShape, x: &[*mut [R; LANES]], skip: bool) {
    // SAFETY: as the caller's.
    unsafe { sample_ops::run::<R>(s, x, skip) }
}

/// [`sample_ops::run`] compiled for AVX-512.
///
/// # Safety
/// The CPU must support AVX-512 F, VL, DQ and BW, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
unsafe fn sample_v4<R: Real>(s: SampleShape, x: &[*mut [R; LANES]], skip: bool) {
    // SAFETY: as the caller's.
    unsafe { sample_ops::run::<R>(s, x, skip) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::kernels::isa;
    use crate::num::formula::tape::Tape;

    /// Inputs a sample sees: vectors of mixed signs, well conditioned
    /// (vector k leans on axis k), scaled by 10⁻³ to 10³ from lane to lane;
    /// then sums, times and counts, positive.
    fn inputs<R: Real>(shape: SampleShape) -> Vec<[R; LANES]> {
        let (n, d) = match shape {
            SampleShape::Lyapunov { d, k } => (k * d, d),
            SampleShape::Chaos { d } => (d, d),
            SampleShape::Alignment { d, m } => (m * d, d),
        };
        (0..shape.inputs())
            .map(|k| {
                std::array::from_fn(|i| {
                    let x = ((k * 37 + i * 11) % 97) as f64 / 97.0 - 0.5;
                    let lean = f64::from(u8::from(k < n && k % d == k / d)) * 4.0;
                    R::from_f64(match k < n {
                        true => (x + lean) * 10f64.powi((i % 7) as i32 - 3),
                        false => 1.0 + 10.0 * x.abs(),
                    })
                })
            })
            .collect()
    }

    /// Every compiled shape computes what the tape does: the same bits
    /// without FMA (the generated loop as any CPU runs it), within a few
    /// roundings at each level this CPU runs, where the compiler fuses
    /// a·b + c into one FMA (the build's `-fp-contract=fast`; the tape
    /// runs one operation at a time). Between skip steps (the skip flag 0)
    /// a Lyapunov sample's own loop leaves the starts as they are, and the
    /// whole program on the tape writes them back unchanged.
    fn same_values<R: Real>(eps: f64) {
        for &shape in SHAPES {
            same_values_at::<R>(shape, eps, true);
            if let SampleShape::Lyapunov { .. } = shape {
                same_values_at::<R>(shape, eps, false);
            }
        }
    }

    /// [`same_values`] for `shape` at the skip step or between.
    fn same_values_at<R: Real>(shape: SampleShape, eps: f64, skip: bool) {
        let levels = [Isa::Baseline, Isa::V3, Isa::V4];
        let program = shape.program();
        let tape = Tape::<R>::new(&program, |_| false);
        let mut x = inputs::<R>(shape);
        if !skip {
            x[shape.inputs() - 1] = [R::from_f64(0.0); LANES];
        }
        let mut regs = vec![[R::default(); LANES]; tape.registers];
        tape.run(&mut regs, &x[..], Isa::Baseline);
        for level in levels.into_iter().filter(|l| *l as u8 <= isa() as u8) {
            let mut y = x.clone();
            let compiled = sample_fn::<R>(shape, level);
            assert_eq!(
                compiled.is_some(),
                level != Isa::Baseline,
                "{shape:?} {level:?}"
            );
            match compiled {
                // SAFETY: only levels this CPU runs.
                Some(f) => unsafe { on_arrays(f, shape, &mut y, skip) },
                // SAFETY: the generated loop at the baseline level.
                None => unsafe { on_arrays(sample_ops::run::<R>, shape, &mut y, skip) },
            }
            if let (SampleShape::Lyapunov { d, k }, false) = (shape, skip) {
                let starts = k * d + 2 * k..k * d + 4 * k;
                assert!(
                    y[starts.clone()] == x[starts.clone()],
                    "{shape:?} {level:?}"
                );
                for j in starts {
                    let bits = |a: &[R; LANES]| a.map(|v| v.to_f64().to_bits());
                    let kept = bits(tape.output(&regs, j)) == bits(&x[j]);
                    assert!(kept, "{shape:?}: the tape's start {j}");
                }
            }
            let tol = match level {
                Isa::Baseline => 0.0,
                _ => 64.0 * eps,
            };
            for (k, got) in y[..program.outputs.len()].iter().enumerate() {
                let want = tape.output(&regs, k);
                for i in 0..LANES {
                    let (g, w) = (got[i].to_f64(), want[i].to_f64());
                    assert!(
                        (g - w).abs() <= tol * w.abs().max(1.0),
                        "{shape:?} {level:?} output {k} lane {i}: {g:e} vs {w:e}"
                    );
                }
            }
        }
    }

    /// The FLI/MEGNO sample of a vector in the band in its two parts, as
    /// a run of steps takes it (`indicators.rs`'s `Pending`): ‖u‖²
    /// (`chaos_n2`), then ln‖w‖ and the sums (`chaos_ln_sums`, lane by
    /// lane), on the program's arrays. Whether `chaos_n2` found the vector
    /// in the band.
    #[inline(always)]
    fn band_parts<R: Real>(x: &mut [[R; LANES]], d: usize) -> bool {
        let mut n2 = [R::from_f64(0.0); LANES];
        let u: Vec<&[R; LANES]> = x[..d].iter().collect();
        let in_band = sample_ops::chaos_n2(&mut n2, &u);
        let (count, inv) = (x[d + 5][0], x[d + 6][0]);
        let [octave, log, max, sum, mean] = &mut x[d..d + 5] else {
            unreachable!("fli_oct and four sums after the vector")
        };
        for i in 0..LANES {
            let (l, m, s, y) = (&mut log[i], &mut max[i], &mut sum[i], &mut mean[i]);
            sample_ops::chaos_ln_sums(l, m, s, y, n2[i], octave[i], count, inv);
        }
        in_band
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn band_parts_v3<R: Real>(x: &mut [[R; LANES]], d: usize) -> bool {
        band_parts(x, d)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
    unsafe fn band_parts_v4<R: Real>(x: &mut [[R; LANES]], d: usize) -> bool {
        band_parts(x, d)
    }

    /// [`band_parts`] compiled for `level`, one this CPU runs.
    fn band_parts_at<R: Real>(level: Isa, x: &mut [[R; LANES]], d: usize) -> bool {
        #[cfg(target_arch = "x86_64")]
        match level {
            // SAFETY: the caller names a level this CPU runs.
            Isa::V4 => return unsafe { band_parts_v4(x, d) },
            Isa::V3 => return unsafe { band_parts_v3(x, d) },
            Isa::Baseline => {}
        }
        let _ = level;
        band_parts(x, d)
    }

    /// The two parts give the bits of the whole program wherever the
    /// vector's ‖u‖² is in the band of `in_band_r`, at every level this CPU
    /// runs (each compiled with the same contraction as the whole program),
    /// and the whole program leaves the vector and its octaves as they
    /// are there: vectors of every ‖u‖² from 2⁻³⁹ to 2⁵⁹, in every
    /// direction.
    fn band_parts_are_the_program<R: Real>() {
        for d in 2..=4 {
            let shape = SampleShape::Chaos { d };
            let mut x = inputs::<R>(shape);
            for i in 0..LANES {
                // ‖u‖² = 2^(−39 + 98·i/63) along a direction turning with i.
                let n2 = 2f64.powf(-39.0 + 98.0 * i as f64 / (LANES - 1) as f64);
                let dir: Vec<f64> = (0..d)
                    .map(|j| ((i * 7 + j * 3) as f64).sin() + 0.1)
                    .collect();
                let norm = dir.iter().map(|v| v * v).sum::<f64>().sqrt();
                for j in 0..d {
                    x[j][i] = R::from_f64(dir[j] / norm * n2.sqrt() * 0.999);
                }
            }
            // A sample's number and one over it are one value per call.
            x[d + 5] = [R::from_f64(37.0); LANES];
            x[d + 6] = [R::from_f64(1.0) / R::from_f64(37.0); LANES];
            for level in [Isa::V3, Isa::V4]
                .into_iter()
                .filter(|l| *l as u8 <= isa() as u8)
            {
                let Some(all) = sample_fn::<R>(shape, level) else {
                    panic!("{shape:?} {level:?} compiled")
                };
                let (mut want, mut got) = (x.clone(), x.clone());
                // SAFETY: only levels this CPU runs.
                unsafe { on_arrays(all, shape, &mut want, true) };
                // Lane 0's ‖u‖² is 0.998·2⁻³⁹, below the band.
                assert!(!band_parts_at(level, &mut got, d), "{shape:?} {level:?}");
                let mut inside = x.clone();
                for j in 0..d {
                    inside[j][0] = inside[j][LANES / 2];
                }
                assert!(band_parts_at(level, &mut inside, d), "{shape:?} {level:?}");
                for k in 0..shape.inputs() {
                    for i in 0..LANES {
                        let bits = |a: &[[R; LANES]]| a[k][i].to_f64().to_bits();
                        assert_eq!(
                            bits(&got),
                            bits(&want),
                            "{shape:?} {level:?} array {k} lane {i}"
                        );
                    }
                }
                assert!(want[..=d] == x[..=d], "{shape:?}: the vector and E stay");
            }
        }
    }

    #[test]
    fn band_parts_are_the_programs() {
        band_parts_are_the_program::<f32>();
        band_parts_are_the_program::<f64>();
    }

    #[test]
    fn compiled_samples_are_the_tape() {
        same_values::<f32>(f32::EPSILON as f64);
        same_values::<f64>(f64::EPSILON);
    }
}
