//! One source for every formula that both backends evaluate.
//!
//! [`shared_fns!`] takes functions written in a restricted Rust syntax and
//!
//! * implements them as a trait for `f32` and for `f64` (the CPU backend calls
//!   `R::name(..)` with `R: Real`), and
//! * keeps their text, which [`to_wgsl`] turns into WGSL for the GPU backend.
//!
//! The restricted syntax is the common part of Rust and WGSL: scalar arguments
//! of type `R` (the working precision), `i32` or `bool`; in/out arguments as
//! `&mut R`; `let`, `let mut` (always with a type when the initialiser is a
//! bare literal, since WGSL would otherwise pick `f32`); `if`/`else`, `while`;
//! arithmetic, comparisons, `&`, `>>`, `<<` on `i32`; calls to other shared
//! functions and to the primitives as `R::name(..)`: `sqrt`, `floor`, `abs`,
//! `min`, `max` (inherent on `f32`/`f64`, builtins in WGSL), `select`,
//! `pow2`, `to_i32`, `rint`, `from_i32`, `inf` ([`crate::num::prims::Prims`] on the CPU,
//! `shaders/prelude_*.wgsl` on the GPU). Every function ends in `return`.
//! The naga test in `tests/suite/shaders.rs` rejects anything outside this subset.

/// Declares shared functions; see the module documentation.
///
/// `shared_fns! { trait Name, wgsl CONST; fn ..(..) {..} ... }` defines
/// `pub trait Name<R = Self>`, implements it for `f32` and `f64`, and defines
/// `pub const CONST: &str` with the Rust text of the functions.
#[macro_export]
macro_rules! shared_fns {
    (
        concrete, wgsl $wg:ident;
        $(
            $(#[$fmeta:meta])*
            fn $name:ident ( $($arg:ident : $aty:ty),* $(,)? ) $(-> $ret:ty)? $body:block
        )*
    ) => {
        $(
            $(#[$fmeta])*
            #[inline(always)]
            #[allow(unused_mut, unused_variables, clippy::needless_return, clippy::excessive_precision, clippy::too_many_arguments, clippy::approx_constant, clippy::assign_op_pattern, clippy::manual_range_contains)]
            pub fn $name($($arg: $aty),*) $(-> $ret)? $body
        )*
        /// Rust text of the shared functions; [`crate::num::dsl::to_wgsl`] makes it WGSL.
        pub const $wg: &str = concat!($( stringify!(fn $name($($arg: $aty),*) $(-> $ret)? $body), "\n", )*);
    };
    (
        $(#[$tmeta:meta])*
        trait $tr:ident, wgsl $wg:ident;
        $(
            $(#[$fmeta:meta])*
            fn $name:ident ( $($arg:ident : $aty:ty),* $(,)? ) $(-> $ret:ty)? $body:block
        )*
    ) => {
        $(#[$tmeta])*
        pub trait $tr<R = Self> {
            $( $(#[$fmeta])* #[allow(clippy::too_many_arguments)] fn $name($($arg: $aty),*) $(-> $ret)?; )*
        }
        const _: () = {
            type R = f32;
            impl $tr for f32 {
                $(
                    #[inline(always)]
                    #[allow(unused_mut, unused_variables, clippy::needless_return, clippy::excessive_precision, clippy::too_many_arguments, clippy::approx_constant, clippy::assign_op_pattern, clippy::manual_range_contains)]
                    fn $name($($arg: $aty),*) $(-> $ret)? $body
                )*
            }
        };
        const _: () = {
            type R = f64;
            impl $tr for f64 {
                $(
                    #[inline(always)]
                    #[allow(unused_mut, unused_variables, clippy::needless_return, clippy::excessive_precision, clippy::too_many_arguments, clippy::approx_constant, clippy::assign_op_pattern, clippy::manual_range_contains)]
                    fn $name($($arg: $aty),*) $(-> $ret)? $body
                )*
            }
        };
        /// Rust text of the shared functions; [`crate::num::dsl::to_wgsl`] makes it WGSL.
        pub const $wg: &str = concat!($( stringify!(fn $name($($arg: $aty),*) $(-> $ret)? $body), "\n", )*);
    };
}

/// A token of the restricted syntax.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Tok {
    Ident(String),
    Num(String),
    Punct(String),
}

/// Why a shared function's text could not become WGSL.
#[derive(Debug, thiserror::Error)]
#[error("shared function text is outside the Rust/WGSL subset: {0}")]
pub struct DslError(pub String);

pub(crate) fn tokenize(src: &str) -> Result<Vec<Tok>, DslError> {
    const PUNCT2: [&str; 16] = [
        "::", "->", "==", "!=", "<=", ">=", "&&", "||", "+=", "-=", "*=", "/=", "<<", ">>", "%=",
        "=>",
    ];
    let b = src.as_bytes();
    let mut i = 0;
    let mut out = Vec::new();
    while i < b.len() {
        let c = b[i] as char;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_alphabetic() || c == '_' {
            let st = i;
            while i < b.len() && ((b[i] as char).is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            out.push(Tok::Ident(src[st..i].to_string()));
        } else if c.is_ascii_digit() {
            let st = i;
            while i < b.len() && (b[i] as char).is_ascii_digit() {
                i += 1;
            }
            if i + 1 < b.len() && b[i] == b'.' && (b[i + 1] as char).is_ascii_digit() {
                i += 1;
                while i < b.len() && (b[i] as char).is_ascii_digit() {
                    i += 1;
                }
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                i += 1;
                if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
                    i += 1;
                }
                while i < b.len() && (b[i] as char).is_ascii_digit() {
                    i += 1;
                }
            }
            if i < b.len() && ((b[i] as char).is_ascii_alphabetic() || b[i] == b'_' || b[i] == b'.')
            {
                return Err(DslError(format!(
                    "number with a suffix, separator or trailing dot near `{}`",
                    &src[st..(i + 1).min(src.len())]
                )));
            }
            out.push(Tok::Num(src[st..i].to_string()));
        } else {
            let two = src.get(i..i + 2).unwrap_or("");
            if PUNCT2.contains(&two) {
                out.push(Tok::Punct(two.to_string()));
                i += 2;
            } else {
                out.push(Tok::Punct(c.to_string()));
                i += 1;
            }
        }
    }
    Ok(out)
}

/// Translates the Rust text of shared functions (from [`shared_fns!`]) to WGSL.
///
/// The WGSL refers to the working precision as `R`, which the prelude
/// declares with `alias R = f32;` or `alias R = f64;`.
pub fn to_wgsl(rust: &str) -> Result<String, DslError> {
    let toks = tokenize(rust)?;
    let mut out: Vec<String> = Vec::with_capacity(toks.len());
    let mut i = 0;
    let is = |k: usize, s: &str| match toks.get(k) {
        Some(Tok::Ident(x)) | Some(Tok::Punct(x)) => x == s,
        _ => false,
    };
    while i < toks.len() {
        match &toks[i] {
            Tok::Ident(id) if (id == "R" || id == "f32" || id == "f64") && is(i + 1, "::") => {
                // `R::name(..)`: the primitive or shared function of the same name.
                i += 2;
            }
            Tok::Ident(id) if id == "let" && is(i + 1, "mut") => {
                out.push("var".into());
                i += 2;
            }
            Tok::Ident(id) if id == "pub" => i += 1,
            Tok::Ident(id) if id == "as" || id == "for" || id == "match" || id == "loop" => {
                return Err(DslError(format!("`{id}` has no WGSL counterpart here")));
            }
            Tok::Punct(p) if p == "&" && is(i + 1, "mut") => {
                let in_type = matches!(out.last().map(String::as_str), Some(":"));
                if in_type {
                    let ty = match toks.get(i + 2) {
                        Some(Tok::Ident(t)) => t.clone(),
                        other => return Err(DslError(format!("`&mut` before {other:?}"))),
                    };
                    out.push(format!("ptr<function, {ty}>"));
                    i += 3;
                } else {
                    out.push("&".into());
                    i += 2;
                }
            }
            Tok::Punct(p) if p == "." || p == "#" || p == "?" || p == "|" || p == "'" => {
                return Err(DslError(format!(
                    "`{p}` (methods, fields, attributes, closures) has no WGSL counterpart"
                )));
            }
            Tok::Ident(s) | Tok::Num(s) | Tok::Punct(s) => {
                out.push(s.clone());
                i += 1;
            }
        }
    }
    // Re-join with line breaks after `;`, `{` and `}` so naga's messages point somewhere useful.
    let mut text = String::with_capacity(rust.len() + rust.len() / 4);
    for t in out {
        text.push_str(&t);
        if t == ";" || t == "{" || t == "}" {
            text.push('\n');
        } else {
            text.push(' ');
        }
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn translates_the_subset() {
        let w = to_wgsl("fn f(x: &mut R, y: R) -> R { let mut a: R = 1.5e-3; *x = R::exp_r(-y * a); g(&mut a); return a; }")
            .unwrap();
        assert!(w.contains("ptr<function, R>"), "{w}");
        assert!(w.contains("var a"), "{w}");
        assert!(w.contains("exp_r ("), "{w}");
        assert!(!w.contains("R ::"), "{w}");
        assert!(w.contains("g ( & a )"), "{w}");
        assert!(w.contains("1.5e-3"), "{w}");
    }

    #[test]
    fn rejects_what_wgsl_lacks() {
        assert!(to_wgsl("fn f(x: R) -> i32 { return x as i32; }").is_err());
        assert!(to_wgsl("fn f(x: R) -> R { return x.abs(); }").is_err());
        assert!(to_wgsl("fn f(x: R) -> R { return 1.0f32; }").is_err());
        assert!(to_wgsl("fn f(x: R) -> R { return 1_000.0; }").is_err());
    }
}
