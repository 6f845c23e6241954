//! The functions a formula may call, and their values in f64.

/// Functions of one argument. `Sign` is internal (the derivative of `abs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Func {
    Sqrt,
    Exp,
    Log,
    Sin,
    Cos,
    Tan,
    Atan,
    Sinh,
    Cosh,
    Tanh,
    Abs,
    Sign,
    /// The chaos indicators' exact rescaling (`octave_r`, `rescale_r` in
    /// `num/math.rs`); not for formulas.
    Octave,
    Rescale,
    /// The chaos indicators' logarithm (`sample_log_r`): `Log` in f64, a
    /// division-free kernel in f32; not for formulas.
    SampleLog,
}

/// Functions of two arguments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Func2 {
    Pow,
    Min,
    Max,
}

/// The functions a formula may call, by name.
pub const FUNCTIONS: &[(&str, Option<Func>, Option<Func2>)] = &[
    ("sqrt", Some(Func::Sqrt), None),
    ("exp", Some(Func::Exp), None),
    ("log", Some(Func::Log), None),
    ("sin", Some(Func::Sin), None),
    ("cos", Some(Func::Cos), None),
    ("tan", Some(Func::Tan), None),
    ("atan", Some(Func::Atan), None),
    ("sinh", Some(Func::Sinh), None),
    ("cosh", Some(Func::Cosh), None),
    ("tanh", Some(Func::Tanh), None),
    ("abs", Some(Func::Abs), None),
    ("pow", None, Some(Func2::Pow)),
    ("min", None, Some(Func2::Min)),
    ("max", None, Some(Func2::Max)),
];

/// A function of one argument, in f64.
pub fn func(f: Func, x: f64) -> f64 {
    match f {
        Func::Sqrt => x.sqrt(),
        Func::Exp => x.exp(),
        Func::Log | Func::SampleLog => x.ln(),
        Func::Sin => x.sin(),
        Func::Cos => x.cos(),
        Func::Tan => x.tan(),
        Func::Atan => x.atan(),
        Func::Sinh => x.sinh(),
        Func::Cosh => x.cosh(),
        Func::Tanh => x.tanh(),
        Func::Abs => x.abs(),
        // sign(0) = 0: the derivative of |x| used at 0 (a subgradient).
        Func::Sign => {
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                x
            }
        }
        Func::Octave => <f64 as crate::num::math::Elementary>::octave_r(x),
        Func::Rescale => <f64 as crate::num::math::Elementary>::rescale_r(x),
    }
}

/// A function of two arguments, in f64.
pub fn func2(f: Func2, x: f64, y: f64) -> f64 {
    match f {
        Func2::Pow => x.powf(y),
        Func2::Min => x.min(y),
        Func2::Max => x.max(y),
    }
}
