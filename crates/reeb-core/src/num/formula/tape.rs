//! The CPU's block interpreter: a [`Lowered`] program run over blocks of
//! `N` trajectories at once, one loop over the lanes per instruction (which
//! the compiler vectorises), so the cost of interpreting an instruction is
//! shared by the whole block. Registers are reused as soon as their value
//! is dead, so a large formula's working set stays in the L1 cache.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use super::dag::{Func, Func2};
use super::lower::{Instr, Lowered, Operand, Prim};
use crate::num::isa::Isa;
use crate::num::precision::Real;

/// An operand resolved for the CPU.
#[derive(Debug, Clone, Copy)]
enum Src<R> {
    Reg(u32),
    /// An input array, by its position in the caller's input list.
    Input(u32),
    /// An input the same in every lane (a value of the whole ensemble).
    Scalar(u32),
    Const(R),
}

#[derive(Debug, Clone, Copy)]
struct Step<R> {
    op: Prim,
    dst: u32,
    a: Src<R>,
    b: Src<R>,
    /// The operation and its operands' kinds in one code, so that the
    /// common instructions cost one dispatch (see [`Code`]); `x` and `y`
    /// are the register or input indices of its first and second operand
    /// that is no constant, `c` its constant.
    code: Code,
    x: u32,
    y: u32,
    c: R,
}

/// The common instructions with their operands' kinds folded in: `R` a
/// register, `I` an input array, `C` a constant. One `match` on it replaces
/// the matches on the operation and on each operand of [`Code::General`],
/// which cost more than the lane loop itself for a block of 64 lanes.
#[rustfmt::skip]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Code {
    AddRR, AddRI, AddIR, AddII, AddRC, AddCR, AddIC, AddCI,
    SubRR, SubRI, SubIR, SubII, SubRC, SubCR, SubIC, SubCI,
    MulRR, MulRI, MulIR, MulII, MulRC, MulCR, MulIC, MulCI,
    DivRR, DivRI, DivIR, DivII, DivRC, DivCR, DivIC, DivCI,
    MaxRR, MaxRI, MaxIR, MaxII, MaxRC, MaxCR, MaxIC, MaxCI,
    MinRR, MinRI, MinIR, MinII, MinRC, MinCR, MinIC, MinCI,
    NegR, NegI, ExpR, ExpI, LogR, LogI, SqrtR, SqrtI, SinR, SinI, CosR, CosI,
    /// Anything else (scalar inputs, the rarer functions): operation and
    /// operands matched one by one.
    General,
}

/// The [`Code`] of `op(a, b)`, with the indices `x`, `y` and the constant
/// of [`Step`].
fn code<R: Real>(op: Prim, a: Src<R>, b: Src<R>) -> (Code, u32, u32, R) {
    use Code::*;
    // An operand's kind (0 register, 1 input, 2 constant), index and value.
    let kind = |o: Src<R>| match o {
        Src::Reg(k) => Some((0, k, R::from_f64(0.0))),
        Src::Input(k) => Some((1, k, R::from_f64(0.0))),
        Src::Const(v) => Some((2, 0, v)),
        Src::Scalar(_) => None,
    };
    let general = (General, 0, 0, R::from_f64(0.0));
    let Some((ka, ia, ca)) = kind(a) else {
        return general;
    };
    if op.unary() {
        let table: [Code; 2] = match op {
            Prim::Neg => [NegR, NegI],
            Prim::Call(Func::Exp) => [ExpR, ExpI],
            Prim::Call(Func::Log) => [LogR, LogI],
            Prim::Call(Func::Sqrt) => [SqrtR, SqrtI],
            Prim::Call(Func::Sin) => [SinR, SinI],
            Prim::Call(Func::Cos) => [CosR, CosI],
            _ => return general,
        };
        return match ka {
            2 => general,
            k => (table[k], ia, 0, ca),
        };
    }
    let Some((kb, ib, cb)) = kind(b) else {
        return general;
    };
    // RR RI IR II RC CR IC CI, by (ka, kb).
    let table: [Code; 8] = match op {
        Prim::Add => [AddRR, AddRI, AddIR, AddII, AddRC, AddCR, AddIC, AddCI],
        Prim::Sub => [SubRR, SubRI, SubIR, SubII, SubRC, SubCR, SubIC, SubCI],
        Prim::Mul => [MulRR, MulRI, MulIR, MulII, MulRC, MulCR, MulIC, MulCI],
        Prim::Div => [DivRR, DivRI, DivIR, DivII, DivRC, DivCR, DivIC, DivCI],
        Prim::Call2(Func2::Max) => [MaxRR, MaxRI, MaxIR, MaxII, MaxRC, MaxCR, MaxIC, MaxCI],
        Prim::Call2(Func2::Min) => [MinRR, MinRI, MinIR, MinII, MinRC, MinCR, MinIC, MinCI],
        _ => return general,
    };
    match (ka, kb) {
        (0, 0) => (table[0], ia, ib, ca),
        (0, 1) => (table[1], ia, ib, ca),
        (1, 0) => (table[2], ia, ib, ca),
        (1, 1) => (table[3], ia, ib, ca),
        (0, 2) => (table[4], ia, 0, cb),
        (2, 0) => (table[5], ib, 0, ca),
        (1, 2) => (table[6], ia, 0, cb),
        (2, 1) => (table[7], ib, 0, ca),
        _ => general,
    }
}

/// A program with registers allocated, in precision `R`.
#[derive(Debug, Clone)]
pub struct Tape<R> {
    steps: Vec<Step<R>>,
    /// The register holding each output.
    outputs: Vec<u32>,
    /// Registers the program needs.
    pub registers: usize,
}

/// Where a tape's inputs come from when it runs: input `k` as an array
/// ([`Inputs::array`]) or, for the inputs the tape was built to read as
/// scalars, as one value for every lane ([`Inputs::scalar`]).
pub trait Inputs<R, const N: usize> {
    fn array(&self, k: u32) -> &[R; N];
    fn scalar(&self, k: u32) -> R;
}

/// Arrays by input index (their first lane as the scalar): tests, and
/// callers whose inputs are one list.
impl<R: Copy, const N: usize> Inputs<R, N> for [[R; N]] {
    fn array(&self, k: u32) -> &[R; N] {
        &self[k as usize]
    }
    fn scalar(&self, k: u32) -> R {
        self[k as usize][0]
    }
}

/// Arrays by reference, by input index: callers whose inputs live in
/// several places (lanes, observer slots).
impl<R: Copy, const N: usize> Inputs<R, N> for [&[R; N]] {
    fn array(&self, k: u32) -> &[R; N] {
        self[k as usize]
    }
    fn scalar(&self, k: u32) -> R {
        self[k as usize][0]
    }
}

impl<R: Real> Tape<R> {
    /// Allocates registers for `l` (a register is free again after the last
    /// instruction that reads it; outputs are never freed). Every output is
    /// in a register, so stores never read an input they overwrite. Inputs
    /// for which `scalar(k)` holds are read as one value for all lanes.
    pub fn new(l: &Lowered, scalar: impl Fn(u32) -> bool) -> Tape<R> {
        let mut instrs: Vec<Instr> = l.instrs.clone();
        let mut outputs: Vec<u32> = vec![];
        for o in &l.outputs {
            outputs.push(match *o {
                Operand::Val(k) => k,
                other => {
                    // x·1 = x exactly, NaN and ±∞ included.
                    instrs.push(Instr {
                        op: Prim::Mul,
                        a: other,
                        b: Operand::Const(1.0),
                    });
                    instrs.len() as u32 - 1
                }
            });
        }
        let last = last_reads(&instrs, &outputs);
        let mut reg = vec![0u32; instrs.len()];
        let mut free: Vec<u32> = vec![];
        let mut registers = 0usize;
        let mut steps = Vec::with_capacity(instrs.len());
        for (k, i) in instrs.iter().enumerate() {
            let src = |o: Operand| match o {
                Operand::Val(v) => Src::Reg(reg[v as usize]),
                Operand::Input(v) if scalar(v) => Src::Scalar(v),
                Operand::Input(v) => Src::Input(v),
                Operand::Const(c) => Src::Const(R::from_f64(c)),
            };
            let (a, b) = (src(i.a), src(i.b));
            // The destination is taken before the operands are freed, so it
            // never aliases them (the interpreter relies on that).
            let dst = free.pop().unwrap_or_else(|| {
                registers += 1;
                (registers - 1) as u32
            });
            reg[k] = dst;
            let (code, x, y, c) = code(i.op, a, b);
            steps.push(Step {
                op: i.op,
                dst,
                a,
                b,
                code,
                x,
                y,
                c,
            });
            let mut operands = [i.a, i.b];
            operands.sort_by_key(|o| {
                if let Operand::Val(v) = o {
                    *v
                } else {
                    u32::MAX
                }
            });
            for (n, o) in operands.iter().enumerate() {
                if let Operand::Val(v) = *o {
                    let dup = n == 1 && operands[0] == *o;
                    if last[v as usize] == k && !dup {
                        free.push(reg[v as usize]);
                    }
                }
            }
        }
        Tape {
            steps,
            outputs: outputs.iter().map(|o| reg[*o as usize]).collect(),
            registers,
        }
    }

    /// Runs the program on a block: `regs` has at least [`Tape::registers`]
    /// arrays. `isa` picks the variant compiled for AVX2 + FMA (or
    /// AVX-512), as the fused kernels do; all variants give the same bits
    /// (no contraction into FMA; reeb's functions use exact FMA anyway).
    pub fn run<const N: usize>(
        &self,
        regs: &mut [[R; N]],
        input: &(impl Inputs<R, N> + ?Sized),
        isa: Isa,
    ) {
        assert!(regs.len() >= self.registers);
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let v3 = has!("avx2") && has!("fma");
            // SAFETY: each variant runs only where the CPU has its features.
            match isa {
                Isa::V4 if v3 && has!("avx512f") => return unsafe { run_v4(self, regs, input) },
                Isa::V3 | Isa::V4 if v3 => return unsafe { run_v3(self, regs, input) },
                _ => {}
            }
        }
        let _ = isa;
        run_body(self, regs, input)
    }

    /// How many outputs the program has.
    pub fn outputs(&self) -> usize {
        self.outputs.len()
    }

    /// The register of output `k` after [`Tape::run`].
    pub fn output<'r, const N: usize>(&self, regs: &'r [[R; N]], k: usize) -> &'r [R; N] {
        &regs[self.outputs[k] as usize]
    }
}

/// The index of the last instruction reading each value (outputs: never).
fn last_reads(instrs: &[Instr], outputs: &[u32]) -> Vec<usize> {
    let mut last = vec![usize::MAX; instrs.len()];
    for (k, i) in instrs.iter().enumerate() {
        for o in [i.a, i.b] {
            if let Operand::Val(v) = o {
                last[v as usize] = k;
            }
        }
    }
    for o in outputs {
        last[*o as usize] = usize::MAX - 1;
    }
    last
}

/// [`run_body`] compiled for AVX2 and FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn run_v3<R: Real, const N: usize>(
    t: &Tape<R>,
    regs: &mut [[R; N]],
    input: &(impl Inputs<R, N> + ?Sized),
) {
    run_body(t, regs, input)
}

/// [`run_body`] compiled for AVX-512.
///
/// # Safety
/// The CPU must support AVX-512 F, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn run_v4<R: Real, const N: usize>(
    t: &Tape<R>,
    regs: &mut [[R; N]],
    input: &(impl Inputs<R, N> + ?Sized),
) {
    run_body(t, regs, input)
}

/// An operand while running: a lane array or one value for every lane.
#[derive(Clone, Copy)]
enum Val<'a, R, const N: usize> {
    Arr(&'a [R; N]),
    One(R),
}

/// A lane's value of an operand (monomorphised per operand kind, so the
/// lane loop stays a plain vector loop).
trait At<R>: Copy {
    fn at(self, i: usize) -> R;
}

impl<R: Copy, const N: usize> At<R> for &[R; N] {
    #[inline(always)]
    fn at(self, i: usize) -> R {
        self[i]
    }
}

/// One value broadcast to every lane.
#[derive(Clone, Copy)]
struct One<R>(R);

impl<R: Copy> At<R> for One<R> {
    #[inline(always)]
    fn at(self, _: usize) -> R {
        self.0
    }
}

/// An operand's lanes (a function, not a closure, so that it is inlined
/// into the instruction loop).
#[inline(always)]
fn fetch<'a, R: Real, const N: usize>(
    base: *mut [R; N],
    input: &'a (impl Inputs<R, N> + ?Sized),
    o: Src<R>,
) -> Val<'a, R, N> {
    match o {
        // SAFETY: below `registers` (asserted by `run`).
        Src::Reg(k) => Val::Arr(unsafe { &*base.add(k as usize) }),
        Src::Input(k) => Val::Arr(input.array(k)),
        Src::Scalar(k) => Val::One(input.scalar(k)),
        Src::Const(v) => Val::One(v),
    }
}

/// `d[i] = f(a[i])` (or `f(a[i], b[i])`) for every lane, `f` called by
/// name. A function passed as `impl Fn` is called through a shim that
/// LLVM does not inline when the body is large (the transcendental
/// functions), and the shim is compiled without the caller's target
/// features: one lane at a time, `fma` and `floor` through libm. Spelled
/// out, the body is inlined into the lane loop of `run_v3`/`run_v4` and
/// vectorised, with the same operations, hence the same bits.
macro_rules! lanes {
    ($d:ident, $f:path, $a:expr) => {{
        let a = $a;
        for i in 0..$d.len() {
            $d[i] = $f(a.at(i));
        }
    }};
    ($d:ident, $f:path, $a:expr, $b:expr) => {{
        let (a, b) = ($a, $b);
        for i in 0..$d.len() {
            $d[i] = $f(a.at(i), b.at(i));
        }
    }};
}

/// The `match` on a [`Code`]: for each binary function its eight codes
/// (operands RR RI IR II RC CR IC CI), for each unary one its two (R I),
/// then what [`Code::General`] runs. `$r!`/`$i!` give a register's or an
/// input's lanes by index; `$x`, `$y` and `$c` are the [`Step`]'s operands.
macro_rules! dispatch {
    ($code:expr, $d:ident, $x:expr, $y:expr, $c:ident, $r:ident, $i:ident;
     $( $f:path => $rr:ident $ri:ident $ir:ident $ii:ident $rc:ident $cr:ident $ic:ident $ci:ident ),*;
     $( $g:path => $ur:ident $ui:ident ),*;
     $general:expr) => {
        match $code {
            $(
                $rr => lanes!($d, $f, $r!($x), $r!($y)),
                $ri => lanes!($d, $f, $r!($x), $i!($y)),
                $ir => lanes!($d, $f, $i!($x), $r!($y)),
                $ii => lanes!($d, $f, $i!($x), $i!($y)),
                $rc => lanes!($d, $f, $r!($x), $c),
                $cr => lanes!($d, $f, $c, $r!($x)),
                $ic => lanes!($d, $f, $i!($x), $c),
                $ci => lanes!($d, $f, $c, $i!($x)),
            )*
            $(
                $ur => lanes!($d, $g, $r!($x)),
                $ui => lanes!($d, $g, $i!($x)),
            )*
            General => $general,
        }
    };
}

#[inline(always)]
fn run_body<R: Real, const N: usize>(
    t: &Tape<R>,
    regs: &mut [[R; N]],
    input: &(impl Inputs<R, N> + ?Sized),
) {
    use Code::*;
    let base = regs.as_mut_ptr();
    for s in &t.steps {
        // SAFETY: below `registers` (asserted by `run`); `dst` differs from
        // the operand registers (`Tape::new`), so the borrows are disjoint.
        let d = unsafe { &mut *base.add(s.dst as usize) };
        macro_rules! r {
            ($k:expr) => {
                unsafe { &*base.add($k as usize) }
            };
        }
        macro_rules! i {
            ($k:expr) => {
                input.array($k)
            };
        }
        let c = One(s.c);
        dispatch!(s.code, d, s.x, s.y, c, r, i;
            add => AddRR AddRI AddIR AddII AddRC AddCR AddIC AddCI,
            sub => SubRR SubRI SubIR SubII SubRC SubCR SubIC SubCI,
            mul => MulRR MulRI MulIR MulII MulRC MulCR MulIC MulCI,
            div => DivRR DivRI DivIR DivII DivRC DivCR DivIC DivCI,
            R::max_r => MaxRR MaxRI MaxIR MaxII MaxRC MaxCR MaxIC MaxCI,
            R::min_r => MinRR MinRI MinIR MinII MinRC MinCR MinIC MinCI;
            neg => NegR NegI,
            R::exp_r => ExpR ExpI,
            R::log_r => LogR LogI,
            R::sqrt => SqrtR SqrtI,
            R::sin_r => SinR SinI,
            R::cos_r => CosR CosI;
            general(s, base, input, d))
    }
}

/// One instruction of [`Code::General`]: the operation and each operand
/// matched in turn.
#[inline(always)]
fn general<R: Real, const N: usize>(
    s: &Step<R>,
    base: *mut [R; N],
    input: &(impl Inputs<R, N> + ?Sized),
    d: &mut [R; N],
) {
    let a = fetch(base, input, s.a);
    if s.op.unary() {
        match a {
            Val::Arr(a) => unary(s.op, d, a),
            Val::One(a) => unary(s.op, d, One(a)),
        }
    } else {
        match (a, fetch(base, input, s.b)) {
            (Val::Arr(a), Val::Arr(b)) => binary(s.op, d, a, b),
            (Val::Arr(a), Val::One(b)) => binary(s.op, d, a, One(b)),
            (Val::One(a), Val::Arr(b)) => binary(s.op, d, One(a), b),
            (Val::One(a), Val::One(b)) => binary(s.op, d, One(a), One(b)),
        }
    }
}

// The four operations by name, for `lanes!`.
#[inline(always)]
fn add<R: Real>(x: R, y: R) -> R {
    x + y
}
#[inline(always)]
fn sub<R: Real>(x: R, y: R) -> R {
    x - y
}
#[inline(always)]
fn mul<R: Real>(x: R, y: R) -> R {
    x * y
}
#[inline(always)]
fn div<R: Real>(x: R, y: R) -> R {
    x / y
}
#[inline(always)]
fn neg<R: Real>(x: R) -> R {
    -x
}

#[inline(always)]
fn map1<R: Real, const N: usize>(d: &mut [R; N], a: impl At<R>, f: impl Fn(R) -> R) {
    for i in 0..N {
        d[i] = f(a.at(i));
    }
}

#[inline(always)]
fn map2<R: Real, const N: usize>(
    d: &mut [R; N],
    a: impl At<R>,
    b: impl At<R>,
    f: impl Fn(R, R) -> R,
) {
    for i in 0..N {
        d[i] = f(a.at(i), b.at(i));
    }
}

#[inline(always)]
fn unary<R: Real, const N: usize>(op: Prim, d: &mut [R; N], a: impl At<R>) {
    match op {
        Prim::Neg => map1(d, a, |x| -x),
        Prim::Call(f) => match f {
            Func::Sqrt => map1(d, a, R::sqrt),
            Func::Exp => lanes!(d, R::exp_r, a),
            Func::Log => lanes!(d, R::log_r, a),
            Func::Sin => lanes!(d, R::sin_r, a),
            Func::Cos => lanes!(d, R::cos_r, a),
            Func::Tan => lanes!(d, R::tan_r, a),
            Func::Atan => lanes!(d, R::atan_r, a),
            Func::Sinh => lanes!(d, R::sinh_r, a),
            Func::Cosh => lanes!(d, R::cosh_r, a),
            Func::Tanh => lanes!(d, R::tanh_r, a),
            Func::Abs => map1(d, a, R::abs),
            Func::Sign => lanes!(d, R::sign_r, a),
            Func::Octave => lanes!(d, R::octave_r, a),
            Func::Rescale => lanes!(d, R::rescale_r, a),
            Func::SampleLog => lanes!(d, R::sample_log_r, a),
        },
        _ => unreachable!("binary operation {op:?} as unary"),
    }
}

#[inline(always)]
fn binary<R: Real, const N: usize>(op: Prim, d: &mut [R; N], a: impl At<R>, b: impl At<R>) {
    match op {
        Prim::Add => map2(d, a, b, |x, y| x + y),
        Prim::Sub => map2(d, a, b, |x, y| x - y),
        Prim::Mul => map2(d, a, b, |x, y| x * y),
        Prim::Div => map2(d, a, b, |x, y| x / y),
        Prim::Call2(Func2::Pow) => lanes!(d, R::pow_r, a, b),
        Prim::Call2(Func2::Min) => map2(d, a, b, R::min_r),
        Prim::Call2(Func2::Max) => map2(d, a, b, R::max_r),
        _ => unreachable!("unary operation {op:?} as binary"),
    }
}

#[cfg(test)]
mod tests {
    use super::super::{compile, lower::lower, Dag};
    use super::*;
    use crate::num::math::{Elementary, Math};

    #[test]
    fn a_block_matches_the_reference_evaluation() {
        let mut d = Dag::new();
        let names = ["q1", "q2", "eps"];
        let texts = [
            "(q1^2 + q2^2)/2 + q1^2*q2 - q2^3/3",
            "eps*sin(2*q1 - 3*q2) / (1 + eps*cos(q2))",
            "sqrt(abs(q1)) + log(1 + q2^2) - atan(q1*q2) + tanh(q1) - pow(abs(q2) + 1, 1.5)",
            "q2",
            "min(q1, q2) * max(q1, eps) + sinh(q1) - cosh(q2) + exp(-q1^2) + tan(q2/4)",
        ];
        let mut roots: Vec<_> = texts
            .iter()
            .map(|t| compile(&mut d, t, &names).unwrap())
            .collect();
        let g = d.gradient(roots[0], &[0, 1]);
        roots.extend(g);
        let tape = Tape::<f64>::new(&lower(&d, &roots), |_| false);
        const N: usize = 8;
        let mut inputs = [[0.0; N]; 3];
        for i in 0..N {
            inputs[0][i] = -1.0 + 0.3 * i as f64;
            inputs[1][i] = 0.7 - 0.2 * i as f64;
            inputs[2][i] = 0.1 * i as f64;
        }
        let mut regs = vec![[0.0; N]; tape.registers];
        tape.run(&mut regs, &inputs[..], Isa::Baseline);
        for i in 0..N {
            let x = [inputs[0][i], inputs[1][i], inputs[2][i]];
            let want = d.eval(&roots, &x);
            for (k, w) in want.iter().enumerate() {
                let got = tape.output(&regs, k)[i];
                assert!(
                    (got - w).abs() <= 1e-14 * w.abs().max(1.0),
                    "root {k} lane {i}: {got} vs {w}"
                );
            }
        }
        assert!(tape.registers < roots.len() + 8, "registers are reused");
    }

    /// Every operation the codes fold, with every kind of operand
    /// (register, input, constant), gives the bits of the operation itself.
    #[test]
    fn every_code_gives_the_operations_bits() {
        const N: usize = 8;
        let mut l = Lowered::default();
        // v0 = input 0 as a register (x·1 = x).
        l.instrs.push(Instr {
            op: Prim::Mul,
            a: Operand::Input(0),
            b: Operand::Const(1.0),
        });
        let operands = [Operand::Val(0), Operand::Input(1), Operand::Const(0.375)];
        let binary = [
            Prim::Add,
            Prim::Sub,
            Prim::Mul,
            Prim::Div,
            Prim::Call2(Func2::Max),
            Prim::Call2(Func2::Min),
        ];
        let unary = [Func::Exp, Func::Log, Func::Sqrt, Func::Sin, Func::Cos].map(Prim::Call);
        let mut cases = vec![];
        for op in binary {
            for a in operands {
                for b in operands {
                    if !matches!((a, b), (Operand::Const(_), Operand::Const(_))) {
                        cases.push((op, a, b));
                    }
                }
            }
        }
        for op in unary.into_iter().chain([Prim::Neg]) {
            for a in &operands[..2] {
                cases.push((op, *a, Operand::Const(0.0)));
            }
        }
        for &(op, a, b) in &cases {
            l.instrs.push(Instr { op, a, b });
            l.outputs.push(Operand::Val(l.instrs.len() as u32 - 1));
        }
        let tape = Tape::<f64>::new(&l, |_| false);
        assert!(tape.steps.iter().all(|s| s.code != Code::General));
        let x: [f64; N] = std::array::from_fn(|i| 0.3 + 0.7 * i as f64);
        let y: [f64; N] = std::array::from_fn(|i| 1.9 - 0.45 * i as f64);
        let mut regs = vec![[0.0; N]; tape.registers];
        tape.run(&mut regs, &[x, y][..], Isa::V4);
        let value = |o: Operand, i: usize| match o {
            Operand::Val(_) => x[i],
            Operand::Input(_) => y[i],
            Operand::Const(c) => c,
        };
        for (k, &(op, a, b)) in cases.iter().enumerate() {
            for i in 0..N {
                let (u, v) = (value(a, i), value(b, i));
                let want = match op {
                    Prim::Add => u + v,
                    Prim::Sub => u - v,
                    Prim::Mul => u * v,
                    Prim::Div => u / v,
                    Prim::Neg => -u,
                    Prim::Call(Func::Exp) => f64::exp_r(u),
                    Prim::Call(Func::Log) => f64::log_r(u),
                    Prim::Call(Func::Sqrt) => u.sqrt(),
                    Prim::Call(Func::Sin) => f64::sin_r(u),
                    Prim::Call(Func::Cos) => f64::cos_r(u),
                    Prim::Call2(Func2::Max) => f64::max_r(u, v),
                    Prim::Call2(Func2::Min) => f64::min_r(u, v),
                    _ => unreachable!(),
                };
                let got = tape.output(&regs, k)[i];
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "{op:?}({a:?}, {b:?}) lane {i}"
                );
            }
        }
    }

    /// A long formula's program reads more than 2¹⁶ inputs (a model's
    /// fixed values) and keeps more than 2¹⁶ values live: neither index
    /// wraps around.
    #[test]
    fn programs_past_two_to_the_sixteen_inputs_and_registers_run() {
        const N: usize = 2;
        let n = 70_000u32;
        let mut l = Lowered::default();
        // v_k = x_k · (k + 1), all live until the sum of them all.
        for k in 0..n {
            l.instrs.push(Instr {
                op: Prim::Mul,
                a: Operand::Input(k),
                b: Operand::Const(k as f64 + 1.0),
            });
        }
        let mut sum = Operand::Val(0);
        for k in 1..n {
            l.instrs.push(Instr {
                op: Prim::Add,
                a: sum,
                b: Operand::Val(k),
            });
            sum = Operand::Val(l.instrs.len() as u32 - 1);
        }
        l.outputs.push(sum);
        let tape = Tape::<f64>::new(&l, |k| k % 2 == 1);
        assert!(tape.registers > 1 << 16, "{} registers", tape.registers);
        let inputs: Vec<[f64; N]> = (0..n).map(|_| [1.0, 2.0]).collect();
        let mut regs = vec![[0.0; N]; tape.registers];
        tape.run(&mut regs, &inputs[..], Isa::Baseline);
        // Σ x_k (k + 1), the odd inputs read as scalars (their lane 0): in
        // lane 1, 2 (k + 1) for even k and k + 1 for odd k.
        let (all, even) = (
            n as f64 * (n as f64 + 1.0) / 2.0,
            (n / 2) as f64 * (n / 2) as f64,
        );
        assert_eq!(tape.output(&regs, 0)[0], all);
        assert_eq!(tape.output(&regs, 0)[1], all + even);
    }
}
