//! Writes `sample_ops.rs`: the chaos indicators' sample programs of the
//! usual shapes as lane loops, printed from the lowered programs
//! `plan/indicators.rs` builds (the ones the tape and WGSL run). The test
//! below fails when the checked-in file differs from what this writes;
//! `REEB_BLESS=1 cargo test --lib sample_ops_are_generated` rewrites it.

use std::fmt::Write;

use crate::models::tangent_gen::{rust_lets, rust_operand};
use crate::num::formula::lower::{Lowered, Operand, Prim};
use crate::num::formula::Func2;
use crate::plan::indicators::{
    chaos_fold_program, chaos_ln_sums_program, chaos_n2_program, chaos_peak_program,
    lyapunov_program_between, SampleShape,
};

/// The shapes compiled: tangent dimensions 2 to 4 (every built-in model,
/// and formula models of up to two degrees of freedom), every number of
/// Lyapunov vectors and of SALI's and GALI's vectors.
fn shapes() -> Vec<SampleShape> {
    let mut out = vec![];
    for d in 2..=4 {
        out.extend((1..=d).map(|k| SampleShape::Lyapunov { d, k }));
        out.push(SampleShape::Chaos { d });
        out.extend((2..=d).map(|m| SampleShape::Alignment { d, m }));
    }
    out
}

fn name(s: SampleShape) -> String {
    match s {
        SampleShape::Lyapunov { d, k } => format!("lyapunov_{d}_{k}"),
        SampleShape::Chaos { d } => format!("chaos_{d}"),
        SampleShape::Alignment { d, m } => format!("alignment_{d}_{m}"),
    }
}

fn pattern(s: SampleShape) -> String {
    match s {
        SampleShape::Lyapunov { d, k } => format!("SampleShape::Lyapunov {{ d: {d}, k: {k} }}"),
        SampleShape::Chaos { d } => format!("SampleShape::Chaos {{ d: {d} }}"),
        SampleShape::Alignment { d, m } => {
            format!("SampleShape::Alignment {{ d: {d}, m: {m} }}")
        }
    }
}

/// One shape's program as a lane loop over its arrays, in place: output k
/// replaces input k (the programs keep their state in that order). The
/// loop takes each array as a reference of its own, which the compiler
/// knows overlaps no other (indexing one slice of arrays, it checked every
/// pair for overlap at run time before each call: a hundred instructions,
/// about the loop's own cost).
fn lane_loop(s: SampleShape) -> String {
    let mut t = lane_loop_of(&name(s), &s.program(), s.inputs());
    if let SampleShape::Lyapunov { d, k } = s {
        let between = lyapunov_program_between(d, k);
        t.push('\n');
        t.push_str(&lane_loop_of(&between_name(s), &between, s.inputs()));
    }
    t
}

/// The Lyapunov sample between skip steps ([`lyapunov_program_between`]).
fn between_name(s: SampleShape) -> String {
    format!("{}_between", name(s))
}

/// [`lane_loop`] of the program `l` of `inputs` arrays, called `name`.
fn lane_loop_of(name: &str, l: &Lowered, inputs: usize) -> String {
    let names = (0..inputs).map(|k| format!("x{k}")).collect::<Vec<_>>();
    let refs = names
        .iter()
        .map(|x| format!("&mut *{x}"))
        .collect::<Vec<_>>();
    let mut t = String::new();
    writeln!(t, "/// # Safety\n/// See [`run`].\n#[inline(always)]").unwrap();
    writeln!(t, "pub unsafe fn {name}<R: Real>(x: &[*mut [R; LANES]]) {{").unwrap();
    writeln!(
        t,
        "    let x: &[*mut [R; LANES]; {inputs}] = x.try_into().expect(\"{inputs} arrays\");"
    )
    .unwrap();
    writeln!(t, "    let [{}] = *x;", names.join(", ")).unwrap();
    writeln!(t, "    unsafe {{ {name}_lanes({}) }};", refs.join(", ")).unwrap();
    t.push_str("}\n\n");
    let lanes = format!("{name}_lanes");
    let arrays = Arrays {
        inputs,
        scalars: 0,
        in_band: false,
    };
    t.push_str(&lanes_fn("#[inline(always)]\n", &lanes, l, arrays));
    t
}

/// The arrays of a lane loop: `inputs` in all, the last `scalars` of them
/// one value for every lane; `in_band`: its logarithm reads a positive
/// normal number, so it calls `sample_log_normal_r`, the same bits without the
/// cases of 0, ∞ and NaN.
#[derive(Clone, Copy)]
struct Arrays {
    inputs: usize,
    scalars: usize,
    in_band: bool,
}

/// What a lane loop returns: nothing, or whether the vector's ‖u‖² (see
/// [`band_operand`]) is in the band of `in_band_r` in every lane
/// (`chaos_n2`, `chaos_peak`: the check in the same pass as the sample's
/// part, not a pass of its own).
#[derive(Clone, Copy, PartialEq)]
enum Returns {
    Nothing,
    InBand,
}

/// `head`, then `fn name` over arrays `x0`, `x1`, … (the first as many as
/// `l` has outputs written, the rest read) running [`lane_body`].
fn lanes_fn(head: &str, name: &str, l: &Lowered, a: Arrays) -> String {
    lanes_fn_returning(head, name, l, a, Returns::Nothing)
}

/// [`lanes_fn`], returning what `r` says.
fn lanes_fn_returning(head: &str, name: &str, l: &Lowered, a: Arrays, r: Returns) -> String {
    let mut t = String::from(head);
    writeln!(t, "fn {name}<R: Real>(").unwrap();
    for k in 0..a.inputs {
        let ty = match k {
            _ if k >= a.inputs - a.scalars => "R",
            _ if k < l.outputs.len() => "&mut [R; LANES]",
            _ => "&[R; LANES]",
        };
        writeln!(t, "    x{k}: {ty},").unwrap();
    }
    match r {
        Returns::Nothing => writeln!(t, ") {{").unwrap(),
        Returns::InBand => writeln!(t, ") -> bool {{\n    let mut out = false;").unwrap(),
    }
    t.push_str(&lane_body(l, a, r));
    if r == Returns::InBand {
        t.push_str("    !out\n");
    }
    t.push_str("}\n");
    t
}

/// One lane of the program `l` as a function of its own: output k over
/// input k (`&mut R`), the other inputs values. A caller's loop keeps a
/// chunk of lanes in registers across several calls (`chaos_ln_sums`, the
/// samples that waited in a run of steps).
fn lane_fn(head: &str, name: &str, l: &Lowered, inputs: usize) -> String {
    let mut t = String::from(head);
    writeln!(t, "fn {name}<R: Real>(").unwrap();
    let written = l.outputs.len();
    for k in 0..inputs {
        let ty = if k < written { "&mut R" } else { "R" };
        writeln!(t, "    x{k}: {ty},").unwrap();
    }
    writeln!(t, ") {{").unwrap();
    let input = |k: u32| match (k as usize) < written {
        true => format!("(*x{k})"),
        false => format!("x{k}"),
    };
    t.push_str(&rust_lets(l, &input, "    "));
    // Every read before any write.
    for (k, o) in l.outputs.iter().enumerate() {
        writeln!(t, "    let o{k}: R = {};", rust_operand(*o, &input)).unwrap();
    }
    for k in 0..written {
        writeln!(t, "    *x{k} = o{k};").unwrap();
    }
    t.push_str("}\n");
    t
}

/// The lane loop of the program `l` on arrays `x0`, `x1`, … (input k in
/// `xk`, output k written over it).
fn lane_body(l: &Lowered, a: Arrays, r: Returns) -> String {
    let mut t = String::new();
    let kept = kept_inputs(l);
    for &k in &kept {
        writeln!(
            t,
            "    let x{k}_in: [R; LANES] = std::hint::black_box(*x{k});"
        )
        .unwrap();
    }
    let scalar = |k: u32| k as usize >= a.inputs - a.scalars;
    let input = |k: u32| match (kept.contains(&k), scalar(k)) {
        (true, _) => format!("x{k}_in[i]"),
        (false, true) => format!("x{k}"),
        (false, false) => format!("x{k}[i]"),
    };
    writeln!(t, "    for i in 0..LANES {{").unwrap();
    let lets = rust_lets(l, &input, "        ");
    match a.in_band {
        true => t.push_str(&normal_logs(&lets)),
        false => t.push_str(&lets),
    }
    if r == Returns::InBand {
        let arg = rust_operand(band_operand(l), &input);
        writeln!(t, "        out |= !R::in_band_r({arg});").unwrap();
    }
    // Every read before any write.
    for (k, o) in l.outputs.iter().enumerate() {
        writeln!(t, "        let o{k}: R = {};", rust_operand(*o, &input)).unwrap();
    }
    for k in 0..l.outputs.len() {
        writeln!(t, "        x{k}[i] = o{k};").unwrap();
    }
    t.push_str("    }\n");
    t
}

/// Generated text whose logarithms read a positive normal number (a
/// vector in the band): `sample_log_normal_r`, the same bits without the
/// cases of 0, ∞ and NaN.
fn normal_logs(text: &str) -> String {
    text.replace("R::sample_log_r(", "R::sample_log_normal_r(")
}

/// The vector's ‖u‖² in a program of [`Returns::InBand`]: the second
/// operand of its maximum (`chaos_peak`), else its one output
/// (`chaos_n2`).
fn band_operand(l: &Lowered) -> Operand {
    match l.instrs.iter().find(|i| i.op == Prim::Call2(Func2::Max)) {
        Some(max) => max.b,
        None => l.outputs[0],
    }
}

/// The written arrays (input k < the number of outputs) that a minimum or
/// a maximum reads: their loops read a copy of them. Where the output is a
/// choice between the input and another value, LLVM stores it as a masked
/// store of the other value (`vmaskmovps` with AVX2), which costs a Zen 3
/// tens of cycles a vector. The copy goes through `black_box`, or the
/// compiler reads the array itself again where it unrolls the loop. It
/// costs a few plain loads and stores.
fn kept_inputs(l: &Lowered) -> Vec<u32> {
    let written = l.outputs.len() as u32;
    let mut kept: Vec<u32> = l
        .instrs
        .iter()
        .filter(|i| matches!(i.op, Prim::Call2(Func2::Min | Func2::Max)))
        .flat_map(|i| [i.a, i.b])
        .filter_map(|o| match o {
            Operand::Input(k) if k < written => Some(k),
            _ => None,
        })
        .collect();
    kept.sort_unstable();
    kept.dedup();
    kept
}

/// The FLI's waiting programs: `chaos_peak_{d}` ([`chaos_peak_program`],
/// the vector by reference; it says whether the vector was in the band)
/// and `chaos_fold` ([`chaos_fold_program`]).
fn waiting_loops() -> String {
    let mut t = String::new();
    for d in 2..=4 {
        let head = "/// The running maximum `x1` of the FLI vector's ‖u‖² after this one, into\n\
                    /// `x0`: whether ‖u‖² is in the band of `in_band_r` in every lane.\n\
                    #[inline(always)]\npub ";
        let name = format!("chaos_peak_{d}");
        let arrays = Arrays {
            inputs: d + 2,
            scalars: 0,
            in_band: false,
        };
        let l = chaos_peak_program(d);
        t.push_str(&lanes_fn_returning(
            head,
            &name,
            &l,
            arrays,
            Returns::InBand,
        ));
        t.push('\n');
    }
    let head = "/// `fli_max` (`x0`) from `fli_oct` (`x1`) and the largest ‖u‖² (`x2`).\n\
                #[inline(always)]\npub ";
    let arrays = Arrays {
        inputs: 3,
        scalars: 0,
        in_band: true,
    };
    t.push_str(&lanes_fn(head, "chaos_fold", &chaos_fold_program(), arrays));
    t
}

/// The FLI/MEGNO sample of a vector in the band in its two parts:
/// `chaos_n2` ([`chaos_n2_program`], the vector by reference, for each
/// dimension; it says whether the vector was in the band) and
/// `chaos_ln_sums` ([`chaos_ln_sums_program`], one lane, the sample's
/// number and one over it as values).
fn band_loops() -> String {
    let mut t = String::from(
        "/// ‖u‖² into `out` of the FLI/MEGNO vector `u` (2 to 4 components):\n\
         /// whether it is in the band of `in_band_r` in every lane.\n\
         #[inline(always)]\n\
         pub fn chaos_n2<R: Real>(out: &mut [R; LANES], u: &[&[R; LANES]]) -> bool {\n    \
         match *u {\n",
    );
    let names = ["a", "b", "c", "e"];
    for d in 2..=4 {
        let u = names[..d].join(", ");
        writeln!(t, "        [{u}] => chaos_n2_{d}(out, {u}),").unwrap();
    }
    t.push_str(
        "        _ => unreachable!(\"no compiled sample of dimension {}\", u.len()),\n    }\n}\n\n",
    );
    for d in 2..=4 {
        let arrays = Arrays {
            inputs: d + 1,
            scalars: 0,
            in_band: false,
        };
        let name = format!("chaos_n2_{d}");
        let l = chaos_n2_program(d);
        let head = "#[inline(always)]\n";
        t.push_str(&lanes_fn_returning(
            head,
            &name,
            &l,
            arrays,
            Returns::InBand,
        ));
        t.push('\n');
    }
    let head = "/// One lane's `fli_log`, `fli_max`, `megno_sum`, `megno_mean` (`x0` to\n\
                /// `x3`) after a sample of ‖u‖² `x4` in the band, `fli_oct` `x5`, its\n\
                /// number `x6`, one over it `x7`.\n\
                #[inline(always)]\npub ";
    let f = lane_fn(head, "chaos_ln_sums", &chaos_ln_sums_program(), 8);
    t.push_str(&normal_logs(&f));
    t
}

/// The text of `sample_ops.rs`.
pub fn generate() -> String {
    let mut s = String::from(
        "//! GENERATED by `backend/cpu/sample_gen.rs` (`REEB_BLESS=1 cargo test --lib\n\
         //! sample_ops_are_generated`); do not edit. The chaos indicators' sample\n\
         //! programs (`plan/indicators.rs`) of the usual shapes, each one loop over\n\
         //! a block's lanes: `x` the inputs in the program's order, output k\n\
         //! written over input k.\n\n\
         #![allow(clippy::all, unused_variables, unused_parens)]\n\n\
         use crate::models::lanes::LANES;\n\
         use crate::num::precision::Real;\n\
         use crate::plan::indicators::SampleShape;\n\n",
    );
    let shapes = shapes();
    writeln!(
        s,
        "/// The shapes compiled here.\npub const SHAPES: &[SampleShape] = &["
    )
    .unwrap();
    for sh in &shapes {
        writeln!(s, "    {},", pattern(*sh)).unwrap();
    }
    s.push_str("];\n\n");
    let most = shapes.iter().map(|sh| sh.inputs()).max().unwrap_or(0);
    writeln!(
        s,
        "/// The most arrays a compiled shape takes.\npub const MOST_ARRAYS: usize = {most};\n"
    )
    .unwrap();
    writeln!(
        s,
        "/// Runs the program of `shape`, one of [`SHAPES`], on the arrays `x`\n\
         /// points to: its inputs in its order, output k written over input k;\n\
         /// `skip`: the sample is the skip step's (else a Lyapunov sample leaves\n\
         /// its starts as they are, `lyapunov_program_between`).\n\
         ///\n\
         /// # Safety\n\
         /// The pointers are valid for reads and writes, aligned and distinct, and\n\
         /// nothing else reads or writes their arrays during the call.\n\
         #[inline(always)]"
    )
    .unwrap();
    writeln!(
        s,
        "pub unsafe fn run<R: Real>(shape: SampleShape, x: &[*mut [R; LANES]], skip: bool) {{"
    )
    .unwrap();
    writeln!(s, "    match shape {{").unwrap();
    for sh in &shapes {
        let (pat, name) = (pattern(*sh), name(*sh));
        if let SampleShape::Lyapunov { .. } = sh {
            let between = between_name(*sh);
            writeln!(s, "        {pat} if !skip => unsafe {{ {between}(x) }},").unwrap();
        }
        writeln!(s, "        {pat} => unsafe {{ {name}(x) }},").unwrap();
    }
    writeln!(
        s,
        "        _ => unreachable!(\"{{shape:?}} is not compiled\"),\n    }}\n}}\n"
    )
    .unwrap();
    for sh in &shapes {
        s.push_str(&lane_loop(*sh));
        s.push('\n');
    }
    s.push_str(&waiting_loops());
    s.push('\n');
    s.push_str(&band_loops());
    s
}

#[cfg(test)]
mod tests {
    #[test]
    fn sample_ops_are_generated() {
        let text = super::generate();
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/backend/cpu/sample_ops.rs");
        if std::env::var("REEB_BLESS").is_ok_and(|v| v == "1") {
            std::fs::write(path, &text).unwrap();
        }
        let have = std::fs::read_to_string(path).unwrap_or_default();
        assert!(
            have == text,
            "src/backend/cpu/sample_ops.rs is not what backend/cpu/sample_gen.rs writes: \
             run `REEB_BLESS=1 cargo test --lib sample_ops_are_generated`"
        );
    }
}
