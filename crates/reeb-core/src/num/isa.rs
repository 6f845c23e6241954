//! Instruction-set levels of x86-64 that reeb compiles its CPU code for:
//! the fused kernels (`backend/cpu/kernels.rs`) and the formula
//! interpreter (`formula/tape.rs`); which one runs is chosen at run time.

/// An instruction-set level of compiled CPU code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    /// Any x86-64 (or other architecture).
    Baseline,
    /// AVX2 + FMA.
    V3,
    /// AVX-512.
    V4,
}

impl Isa {
    /// The level's name, as `REEB_CPU_ISA` spells it, with its features.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline (x86-64 SSE2, or the target's default)",
            Isa::V3 => "v3 (AVX2 + FMA)",
            Isa::V4 => "v4 (AVX-512)",
        }
    }

    /// Its instruction set in a word: "AVX-512", "AVX2 + FMA", "portable".
    pub fn label(self) -> &'static str {
        match self {
            Isa::Baseline => "portable (no AVX2)",
            Isa::V3 => "AVX2 + FMA",
            Isa::V4 => "AVX-512",
        }
    }
}

/// Defines a function whose body is compiled for AVX2 and FMA where the
/// CPU has them, else as it is: for tests that run an elementary function
/// over every f32, whose `fma`s the baseline build calls from libm (six
/// times slower on a Zen 3). `fma` is exact either way, so a function without an
/// a·b + c the compiler could contract gives the same bits in both. (The
/// body is a function of its own, `#[inline(always)]`, called from both
/// variants: a closure handed to a `#[target_feature]` function is not
/// reliably inlined there.)
#[macro_export]
macro_rules! with_fma {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($a:ident: $t:ty),* $(,)?) $(-> $r:ty)? $body:block) => {
        $(#[$m])*
        $vis fn $name($($a: $t),*) $(-> $r)? {
            #[inline(always)]
            fn body($($a: $t),*) $(-> $r)? $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            unsafe fn v3($($a: $t),*) $(-> $r)? {
                body($($a),*)
            }
            #[cfg(target_arch = "x86_64")]
            {
                use std::arch::is_x86_feature_detected as has;
                if has!("avx2") && has!("fma") {
                    // SAFETY: the CPU has the features `v3` is compiled for.
                    return unsafe { v3($($a),*) };
                }
            }
            body($($a),*)
        }
    };
}
