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
