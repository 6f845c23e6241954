//! WGSL for a plan: `shaders/prelude_*.wgsl`, the shared functions (translated
//! from their single Rust source by [`crate::num::dsl::to_wgsl`]) and
//! `shaders/driver.wgsl`, with the plan's code spliced in.
//!
//! The kernel is specialised: it declares only the variables the plan's ops
//! name, loads and stores only the integrated ones, bakes constant inputs in as
//! literals, reads time only when the plan has time, and contains observer code
//! only for the observers asked for. Observer code calls the same shared
//! functions (`models/events.rs`) as the CPU's `backend/cpu/observe.rs`.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

use crate::models::formula::{Composed, Cost, FormulaModel};
use crate::models::COMMON_WGSL;
use crate::num::dsl::to_wgsl;
use crate::num::formula::stage::{split, Staged, Vary};
use crate::num::formula::wgsl::{function_text, lit};
use crate::num::math::{
    ELEMENTARY_WGSL, LOG_ATAN_F32_WGSL, LOG_ATAN_F64_WGSL, MATH_F32_WGSL, MATH_F64_WGSL,
};
use crate::num::precision::Precision;
use crate::plan::indicators::{chaos_fli_program, Indicators, SampleInput};
use crate::plan::section::{Recorded, SectionKind, SectionStep};
use crate::plan::slots;
use crate::plan::tangent::{TangentInput, TangentStep};
use crate::plan::{ObsVar, Op, Plan, Source, StopPlan};

use super::time_table::TimeTable;
use super::tuning::Launch;

const PRELUDE_F32: &str = include_str!("../../../shaders/prelude_f32.wgsl");
const PRELUDE_F64: &str = include_str!("../../../shaders/prelude_f64.wgsl");

/// The f64 prelude's `pow2` where the adapter has SHADER_INT64: the sum
/// n + 1.5·2⁵² + 1023 holds n + 1023 in its low bits, and the shift by 52
/// moves them into the exponent field (the CPU's twin, `Prims::pow2`). No
/// conversions, which NVIDIA runs at a quarter of the f64 FMA rate: van der
/// Pol S2 in f64 went from 3.08·10¹¹ to 4.37·10¹¹ trajectory-steps/s on an
/// H200 with it.
const POW2_F64_INT64: &str = "fn pow2(n: f64) -> f64 {
    return bitcast<f64>(bitcast<u64>(n + 6755399441056767.0) << 52u);
}";

/// The f64 prelude's `pow2` without 64-bit integers; pow2i gives the
/// subnormal at n = −1023, hence the select.
const POW2_F64_PORTABLE: &str = "fn pow2(n: f64) -> f64 {
    let m = i32(n);
    return select(pow2i(m), 0.0, m < -1022);
}";
/// The f64 prelude's `log_split_f64` from the bits (`log_f64_bits` on the
/// CPU): where the ladder of 20 scalings took a fifth of an f64 FLI run on
/// lavapipe (spin–orbit cost scene). WGSL's select takes no abstract
/// literal for f64, hence the typed constants.
const LOG_SPLIT_F64_INT64: &str = "fn log_split_f64(x: f64) -> f64 {
    let tiny = x < 2.2250738585072014e-308;
    let bits = bitcast<u64>(select(x, x * 1.8446744073709552e19, tiny));
    let e = f64(u32((bits >> 52u) & 0x7fflu)) - select(f64(1023.0), f64(1087.0), tiny);
    let m = bitcast<f64>((bits & 0x000ffffffffffffflu) | 0x3ff0000000000000lu);
    let normal = x > 0.0 && x <= 1.7976931348623157e308;
    return log_kernel_f64(x, select(x, m, normal), select(f64(0.0), e, normal));
}";

/// The f64 prelude's `log_split_f64` without 64-bit integers.
const LOG_SPLIT_F64_PORTABLE: &str = "fn log_split_f64(x: f64) -> f64 {
    return log_f64(x);
}";
/// The f64 prelude's `sample_log_r` from the bits: x = 2^k·m with m in
/// [√½, √2) read from the bits offset by √½'s mantissa (the CPU's
/// `log_normal_f64`, after subnormals are scaled as `log_split_f64` scales
/// them), into fdlibm's kernel on that m: the m and k `log_core_f64`
/// makes, so the same bits, without its compare, selects and halving; then
/// the cases of 0, < 0, ∞ and NaN as `log_kernel_f64` takes them.
const SAMPLE_LOG_F64_INT64: &str = "fn sample_log_r(x: f64) -> f64 {
    let tiny = x < 2.2250738585072014e-308;
    let ix = bitcast<u64>(select(x, x * 1.8446744073709552e19, tiny)) - 0x0006a09e667f3bcelu;
    let k = f64(u32(ix >> 52u)) - select(f64(1022.0), f64(1086.0), tiny);
    let m = bitcast<f64>((ix & 0x000ffffffffffffflu) + 0x3fe6a09e667f3bcelu);
    let res = log_reduced_f64(m, k);
    let r1 = select(x, res, x > 0.0 && x <= 1.7976931348623157e308);
    let r2 = select(r1, -inf(), x == 0.0);
    return select(r2, quiet_nan(), x < 0.0);
}";

/// The f64 prelude's `sample_log_r` without 64-bit integers: `log_r`'s.
const SAMPLE_LOG_F64_PORTABLE: &str = "fn sample_log_r(x: f64) -> f64 {
    return log_split_f64(x);
}";
const DRIVER: &str = include_str!("../../../shaders/driver.wgsl");

/// The f32 prelude's `exp` as reeb's polynomial (`Math::exp_f32`): the
/// CPU's function (within 2 ULP of its bits on lavapipe, which contracts
/// a·b + c into fma where the CPU rounds twice).
const EXP_F32_EXACT: &str = "fn exp_r(x: f32) -> f32 {
    return exp_f32(x);
}";

/// The f32 prelude's `exp` from the adapter's `exp2`: x·log₂e split into
/// t (rounded) and e (its error, exact by fma, plus x times log₂e's own
/// error), then 2ᵗ·(1 + e·ln 2). Within 1 ULP of exp with a correctly
/// rounded exp2; the driver's exp2 adds its own error (measured by
/// `gpu::accuracy` and `reeb doctor`). Clamped by select, so that NaN
/// passes, to [−104, 89], where 2ᵗ is +0 below (t < −150) and +∞ above
/// (exp2 of ±∞ would meet e = NaN); where 2ᵗ is +∞ it is the result
/// itself, since ∞·(1 + e·ln 2) is NaN for e < 0.
/// Eight operations and the exp2, where the polynomial takes about twenty:
/// on an H200, van der Pol S2 in f32 went from 9.9·10¹¹ to 1.36·10¹²
/// trajectory-steps/s with exp2 on reeb's reduced argument (this form,
/// with no reduction, is not measured there yet).
const EXP_F32_HARDWARE: &str = "fn exp_r(x: f32) -> f32 {
    let lo = select(x, -104.0, x < -104.0);
    let xc = select(lo, 89.0, lo > 89.0);
    let t = xc * 1.44269502;
    let e = fma(xc, 1.925963e-8, fma(xc, 1.44269502, -t));
    let y = exp2(t);
    return select(fma(y, e * 0.693147182, y), y, t >= 128.0);
}";

/// How a kernel computes what the adapter may compute its own way: the
/// device's choice (`GpuContext::forms`), not the launch's, since the exp
/// form changes the results (the launch never does).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Forms {
    /// SHADER_INT64: the f64 `pow2` and the logarithm's 2^e·m from the
    /// bits (the same values).
    pub int64: bool,
    /// The f32 `exp` (f64 kernels have no hardware exp).
    pub exp: ExpForm,
}

/// The f32 `exp` of a kernel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ExpForm {
    /// reeb's polynomial, the CPU's function.
    #[default]
    Exact,
    /// The adapter's exp2 on a split argument (a few ULP).
    Hardware,
}

impl ExpForm {
    pub fn name(self) -> &'static str {
        match self {
            ExpForm::Exact => "exact",
            ExpForm::Hardware => "hardware",
        }
    }
}

/// A generated kernel and what the host needs to drive it.
#[derive(Debug, Clone)]
pub struct Kernel {
    /// The kernel with the default launch ([`Launch::default`]).
    pub source: String,
    /// The kernel with the launch's markers (`{{WORKGROUP}}`, …) and the
    /// adapter's (`{{POW2_F64}}`, `{{EXP_F32}}`) left to fill
    /// ([`Kernel::source_for`]).
    template: String,
    /// What blocks of steps are written from, in a kernel without observers.
    blocks: Option<BlockParts>,
    /// Values of the axis-dependent inputs, concatenated (uploaded as `table`).
    pub table: Vec<f64>,
    /// Whether the stroboscopic section samples exactly (no interpolation).
    pub strobe_exact: bool,
    /// Time terms the host tabulates per window (uniform `tterms`), if the
    /// ensemble shares them.
    pub time_table: Option<TimeTable>,
    /// The most steps a window may take within [`LOOP_ITERATIONS`].
    pub max_window: u64,
}

/// A kernel's step, its finite test and its variables, from which
/// [`blocks`] writes blocks of steps.
#[derive(Debug, Clone)]
struct BlockParts {
    vars: Vec<String>,
    step: String,
    finite: String,
}

/// llvmpipe (lavapipe) silently ends a shader's loops once they have run
/// this many iterations in one invocation, counted together over all its
/// loops (gallivm keeps one loop limiter per function, and inlines every
/// function). Kernels keep loops out of their steps where they can
/// (`crossing_theta` is written out) and windows stay within the limit
/// ([`max_window`]); a thread whose loop ends early anyway says so
/// (`slots::CUT`) and the run fails.
pub const LOOP_ITERATIONS: u64 = 65_535;

/// The most steps a window of a kernel with `section` may take: one loop iteration
/// per step, and with a section that may find several points in a step
/// (its loop entered after the first) as many more per step as a step holds
/// points: the lanes that one llvmpipe thread runs together share the
/// iterations of any of them.
fn max_window(section: Option<&SectionStep>) -> u64 {
    match section.map_or(1, |s| s.max_per_step) {
        1 => LOOP_ITERATIONS,
        m => ((LOOP_ITERATIONS - 16) / (1 + m)).max(1),
    }
}

/// The window's steps in blocks of `b` ([`Launch::finite_block`]) with one
/// finite test each, ahead of the loop that tests every step: a block that
/// ends non-finite puts the state back as it was at the block's start and
/// leaves it to that loop, which finds the step (the steps are the same
/// operations, so the same bits) and sets the status. Without the test per
/// step the f32 van der Pol S2 step ran 23 % faster on an H200 (16 % in
/// f64); the steps after a non-finite one within a block only compute NaNs
/// and infinities. Observers see every step, so kernels with any keep the
/// loop alone.
fn blocks(parts: &BlockParts, b: u32) -> String {
    let BlockParts { vars, step, finite } = parts;
    let keep: String = vars
        .iter()
        .map(|v| format!("        let block_{v} = {v};\n"))
        .collect();
    let restore: String = vars
        .iter()
        .map(|v| format!("            {v} = block_{v};\n"))
        .collect();
    // Written out rather than an inner loop: on lavapipe the inner loop
    // made the step 8 % slower than testing every step, written out 5 %.
    let steps: String = (0..b)
        .map(|k| {
            format!(
                "        {{\n            let n: u32 = block_n + {k}u;\n            let nf: R = R(n);\n{}        }}\n",
                indent(step, 4)
            )
        })
        .collect();
    format!(
        "    // Blocks of {b} steps, one finite test each (codegen.rs, `blocks`).
    loop {{
        if u.step0 + u.nsteps - n < {b}u {{
            break;
        }}
{keep}        let block_n = n;
{steps}        if !({finite}) {{
{restore}            break;
        }}
        n = n + {b}u;
    }}"
    )
}

/// Why no kernel could be generated.
#[derive(Debug, thiserror::Error)]
pub enum CodegenError {
    #[error(transparent)]
    Dsl(#[from] crate::num::dsl::DslError),
    #[error("{0}")]
    Plan(String),
}

/// Arguments of every shared function in `wgsl`: name → [(argument, by pointer)].
pub fn signatures(wgsl: &str) -> BTreeMap<String, Vec<(String, bool)>> {
    let mut out = BTreeMap::new();
    let mut rest = wgsl;
    while let Some(pos) = rest.find("fn ") {
        let after = &rest[pos + 3..];
        let name: String = after
            .trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let Some(open) = after.find('(') else { break };
        // Arguments end at the parenthesis that closes the list.
        let mut depth = 0;
        let mut end = open;
        for (k, c) in after[open..].char_indices() {
            match c {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + k;
                        break;
                    }
                }
                _ => {}
            }
        }
        let args = &after[open + 1..end];
        let mut list = vec![];
        let mut depth = 0;
        let mut cur = String::new();
        for c in args.chars().chain(std::iter::once(',')) {
            match c {
                '<' => {
                    depth += 1;
                    cur.push(c)
                }
                '>' => {
                    depth -= 1;
                    cur.push(c)
                }
                ',' if depth == 0 => {
                    if let Some((n, ty)) = cur.split_once(':') {
                        list.push((n.trim().to_string(), ty.trim().starts_with("ptr")));
                    }
                    cur.clear();
                }
                _ => cur.push(c),
            }
        }
        out.insert(name, list);
        rest = &after[end..];
    }
    out
}

/// A formula model's whole step as the kernel runs it: composed, split by
/// what its values vary with, and the table of its shared values if any.
struct FormulaKernel {
    step: Composed,
    parts: Staged,
    table: Option<TimeTable>,
}

impl FormulaKernel {
    fn of(plan: &Plan) -> Option<FormulaKernel> {
        let m = plan.model.formula()?;
        // Where the ensemble shares `t0` and `dt`, the table holds the shared
        // values: the program with the least per-lane work is the cheapest.
        if !plan.on_axis("t0") && !plan.on_axis("dt") {
            let step = m.compose(&plan.ops, Cost::PerLane)?;
            let parts = split(&step.program, &step.vary(|n| plan.on_axis(n)));
            if let Some(table) = TimeTable::of_formula(&step, &parts) {
                return Some(FormulaKernel {
                    step,
                    parts,
                    table: Some(table),
                });
            }
        }
        // Else every thread computes all that changes per step (what no
        // step changes before its step loop): the least per-step work.
        let step = m.compose(&plan.ops, Cost::PerStep)?;
        let per_thread: Vec<Vary> = step
            .inputs
            .iter()
            .map(|n| Vary {
                lane: true,
                step: step.changes_each_step(n),
            })
            .collect();
        let parts = split(&step.program, &per_thread);
        Some(FormulaKernel {
            step,
            parts,
            table: None,
        })
    }
}

/// All shared-function text a plan's kernel includes, translated.
fn shared_text(
    plan: &Plan,
    precision: Precision,
    formula: Option<&FormulaKernel>,
    moves_state: bool,
    time_table: Option<&TimeTable>,
) -> Result<String, CodegenError> {
    let mut text = math_text(precision)?;
    for t in COMMON_WGSL.iter().chain(plan.model.spec().wgsl) {
        text.push_str(&to_wgsl(t)?);
    }
    if let Some(stop) = &plan.stop {
        text.push_str(&stop_function(stop));
    }
    if let Some(ind) = &plan.indicators {
        let tabled = time_table.is_some_and(|tt| !tt.ops().is_empty());
        text.push_str(&indicator_functions(plan, ind, moves_state, tabled)?);
    }
    // A formula model's ops are emitted as WGSL directly (num/formula/wgsl.rs).
    if let Some(m) = plan.model.formula() {
        text.push_str(&m.wgsl());
        if let Some(f) = formula {
            text.push_str(&FormulaModel::step_wgsl(&f.step, &f.parts));
        }
    }
    Ok(text)
}

/// Values per trajectory frame in `traj_out`: the recorded variables', then
/// the indicators' slots that make their running values.
pub(super) fn frame_width(plan: &Plan) -> usize {
    plan.trajectory_vars.len() + slots::indicator_frame_slots(plan).len()
}

/// The chaos indicators' programs as WGSL functions over the kernel's
/// locals: `tangent_step` (the state at the step's start is `prev_<v>`,
/// the step number `nf`, the deviation vectors the slots `w<k>_<j>`; with
/// `moves_state` it writes the state after the step into the variables
/// too, and is the step), and `lyapunov_sample`, `chaos_sample`,
/// `alignment_sample` over the
/// slots and the locals `count`, `inv_count`, `at_skip`.
fn indicator_functions(
    plan: &Plan,
    ind: &Indicators,
    moves_state: bool,
    tabled: bool,
) -> Result<String, CodegenError> {
    // The indicators' slots are real slots from `first` on.
    let first = slots::indicator_first(plan);
    let slot_names: Vec<String> = slots::real(plan)
        .into_iter()
        .skip(first)
        .map(|(n, _)| n)
        .collect();
    // The step's time terms from the window's table, as the step reads
    // them, where it has one (else the tangent computes them for every
    // trajectory: Kepler's equation for each spin–orbit orbit and step).
    let (vectors, spec) = (ind.tangent.vectors, plan.step_spec());
    let built = match (moves_state, tabled) {
        (true, true) => Some(TangentStep::with_state_tabled(&spec, vectors)),
        (true, false) => Some(TangentStep::with_state(&spec, vectors)),
        (false, true) => Some(TangentStep::tabled(&spec, vectors)),
        (false, false) => None,
    };
    let built = built
        .transpose()
        .map_err(|e| CodegenError::Plan(e.message))?;
    let tangent = built.as_ref().unwrap_or(&ind.tangent);
    let tangent_inputs: Vec<String> = tangent
        .inputs
        .iter()
        .map(|i| match *i {
            TangentInput::Lane(v) if plan.vars.contains(&v) => format!("prev_{v}"),
            TangentInput::Lane(name) => name.to_string(),
            TangentInput::Step => "nf".into(),
            TangentInput::TimeTerm { stage, term } => table_term(stage, term),
            d => slot_names[ind.deviation_slot(d).expect("a deviation")].clone(),
        })
        .collect();
    let outputs =
        |slots: &[usize]| -> Vec<String> { slots.iter().map(|k| slot_names[*k].clone()).collect() };
    let mut tangent_outputs = outputs(&ind.deviation_slots);
    if moves_state {
        tangent_outputs.extend(plan.vars.iter().map(|v| v.to_string()));
    }
    let mut text = function_text(
        "tangent_step",
        &tangent.program,
        &strs(&tangent_inputs),
        &strs(&tangent_outputs),
    );
    for (name, s) in ind.samplers() {
        let inputs: Vec<String> = s
            .inputs
            .iter()
            .map(|i| match *i {
                SampleInput::Slot(k) => slot_names[k].clone(),
                SampleInput::Count => "count".into(),
                SampleInput::InvCount => "inv_count".into(),
                SampleInput::AtSkip => "at_skip".into(),
            })
            .collect();
        // The FLI alone takes the program without MEGNO's sums. Every
        // sample runs whole here: the CPU's wait in the band (the largest
        // ‖u‖² kept, one logarithm when `fli_max` is read) took 1.2–1.5×
        // the time on lavapipe (whole runs of the cost scenes), van der
        // Pol's too, whose vectors never leave the band: lavapipe seems to
        // run both sides of a branch its invocations may disagree on.
        let fli_alone = name == "chaos_sample" && plan.observers.megno.is_none();
        let program = match fli_alone {
            true => chaos_fli_program(ind.tangent.space.len()),
            false => s.program.clone(),
        };
        text.push_str(&function_text(
            name,
            &program,
            &strs(&inputs),
            &strs(&outputs(&s.outputs)),
        ));
    }
    Ok(text)
}

/// The tangent program's local for time term `term` of stage `stage`
/// ([`TangentInput::TimeTerm`]).
fn table_term(stage: usize, term: usize) -> String {
    format!("tt{stage}_{term}")
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// `fn stop_value(…, stop_g: ptr<function, R>)`: the stop condition's
/// `lhs − rhs` over the kernel's locals (`t` as `stop_t`, the step's end).
fn stop_function(stop: &StopPlan) -> String {
    let inputs: Vec<&str> = stop
        .inputs
        .iter()
        .map(|n| if *n == "t" { "stop_t" } else { n })
        .collect();
    function_text("stop_value", &stop.program, &inputs, &["stop_g"])
}

/// Generates the kernel of `plan` in `precision`.
pub fn generate(plan: &Plan, precision: Precision) -> Result<Kernel, CodegenError> {
    let formula = FormulaKernel::of(plan);
    let time_table = match &formula {
        Some(f) => f.table.clone(),
        None => TimeTable::of(plan),
    };
    // With chaos indicators, the tangent program moves the state too (it
    // computes the step anyway), where the step is a built-in model's, its
    // time terms its own or the window's table's: the step's sin and cos
    // (the spin–orbit kick's of 2q) are then computed once, not once for
    // the step and again for the tangent (lavapipe, spin–orbit cost scene,
    // one exponent: 2.24 → 1.36 plain runs in f32, 2.08 → 1.48 in f64).
    let moves_state = plan.indicators.is_some() && plan.model.formula().is_none();
    let shared = shared_text(
        plan,
        precision,
        formula.as_ref(),
        moves_state,
        time_table.as_ref(),
    )?;
    let sigs = signatures(&shared);
    let names = bound_names(plan, &sigs)?;
    // Room for every axis at once: growing by doubling would copy a table
    // of 10⁷ initial values a few times over.
    let room = plan.bindings.iter().map(|(_, src)| match src {
        Source::Axis { values, .. } => values.len(),
        Source::Const(_) => 1,
    });
    let mut table: Vec<f64> = Vec::with_capacity(room.sum());
    let mut g = Gen {
        plan,
        moves_state,
        section: plan.section(),
        sigs: &sigs,
        names: &names,
        time_table: time_table.as_ref(),
        load: String::new(),
        store: String::new(),
    };
    let inputs = g.inputs(precision, &mut table)?;
    g.state(precision, &mut table)?;
    g.formula_fixed();
    let step = g.step();
    // `&`, not `&&`: naga lowers a short-circuit `&&` to an `if` that
    // stores into a local, once per step; the tests have no side effects.
    // (One finite test of Σ x·2⁻ᵐ instead measured the same on an H200.)
    let finite = plan
        .vars
        .iter()
        .map(|v| format!("finite({v})"))
        .collect::<Vec<_>>()
        .join(" & ");
    let strobe_exact = g.exact_section();
    let (begin, observe) = g.observers();
    // Without observers the steps may run in blocks (`blocks`); their
    // loop takes fewer iterations than the loop of single steps.
    let blocks = observe.trim().is_empty().then(|| BlockParts {
        vars: plan.vars.iter().map(|v| v.to_string()).collect(),
        step: step.clone(),
        finite: finite.clone(),
    });
    let max_window = max_window(g.section.as_ref());

    let prelude = match precision {
        Precision::F32 => PRELUDE_F32,
        Precision::F64 => PRELUDE_F64,
    };
    let tterms = match &time_table {
        Some(_) => format!(
            "@group(0) @binding(8) var<uniform> tterms: array<vec4<R>, {}>;",
            TimeTable::capacity(precision.bytes() as u64)
        ),
        None => String::new(),
    };
    let driver = DRIVER
        .replace("{{TIME_TABLE}}", &tterms)
        .replace("{{INPUTS}}", inputs.trim_end())
        .replace("{{LOAD}}", g.load.trim_end())
        .replace("{{BEGIN}}", begin.trim_end())
        .replace("{{STEP}}", step.trim_end())
        .replace("{{FINITE}}", &finite)
        .replace("{{OBSERVE}}", observe.trim_end())
        .replace("{{STORE}}", g.store.trim_end())
        .replace("{{CUT}}", &slots::CUT.to_string());
    let template = format!("{prelude}\n// ---- shared functions (generated from src/**/*.rs) ----\n{shared}\n// ---- driver ----\n{driver}");
    Ok(Kernel {
        source: launched(&template, None, &Launch::default(), Forms::default()),
        template,
        blocks,
        table,
        strobe_exact,
        time_table,
        max_window,
    })
}

impl Kernel {
    /// The kernel's source for `launch` (its workgroup size, and the
    /// trajectories each invocation integrates) in the device's `forms`.
    pub fn source_for(&self, launch: &Launch, forms: Forms) -> String {
        launched(&self.template, self.blocks.as_ref(), launch, forms)
    }

    /// Can its steps run in blocks ([`Launch::finite_block`])?
    pub fn has_blocks(&self) -> bool {
        self.blocks.is_some()
    }
}

fn launched(template: &str, parts: Option<&BlockParts>, launch: &Launch, forms: Forms) -> String {
    let blocks = match (parts, launch.finite_block) {
        (Some(parts), b) if b > 1 => blocks(parts, b),
        _ => String::new(),
    };
    fill_forms(template, forms)
        .replace("{{WORKGROUP}}", &launch.workgroup.to_string())
        .replace("{{PER_THREAD}}", &launch.per_thread.to_string())
        .replace("{{BLOCKS}}", &blocks)
}

/// `text` with the adapter's forms of `pow2` and the log's split (f64)
/// and `exp` (f32).
fn fill_forms(text: &str, forms: Forms) -> String {
    let (pow2, log, sample_log) = match forms.int64 {
        true => (POW2_F64_INT64, LOG_SPLIT_F64_INT64, SAMPLE_LOG_F64_INT64),
        false => (
            POW2_F64_PORTABLE,
            LOG_SPLIT_F64_PORTABLE,
            SAMPLE_LOG_F64_PORTABLE,
        ),
    };
    let exp = match forms.exp {
        ExpForm::Exact => EXP_F32_EXACT,
        ExpForm::Hardware => EXP_F32_HARDWARE,
    };
    text.replace("{{POW2_F64}}", pow2)
        .replace("{{LOG_SPLIT_F64}}", log)
        .replace("{{SAMPLE_LOG_F64}}", sample_log)
        .replace("{{EXP_F32}}", exp)
}

/// The prelude and the math functions of `precision` in `forms`, without a
/// driver: for kernels that evaluate the primitives (`gpu::accuracy`).
pub fn math_source(precision: Precision, forms: Forms) -> Result<String, CodegenError> {
    let prelude = match precision {
        Precision::F32 => PRELUDE_F32,
        Precision::F64 => PRELUDE_F64,
    };
    Ok(fill_forms(
        &format!("{prelude}\n{}", math_text(precision)?),
        forms,
    ))
}

/// The math functions every kernel of `precision` includes, translated.
fn math_text(precision: Precision) -> Result<String, CodegenError> {
    let (math, log_atan) = match precision {
        Precision::F32 => (MATH_F32_WGSL, LOG_ATAN_F32_WGSL),
        Precision::F64 => (MATH_F64_WGSL, LOG_ATAN_F64_WGSL),
    };
    let mut text = String::new();
    for t in [math, log_atan, ELEMENTARY_WGSL] {
        text.push_str(&to_wgsl(t)?);
    }
    Ok(text)
}

/// Every name the plan's ops bind (their shared functions' arguments), plus
/// the inputs the driver and observers read.
fn bound_names(
    plan: &Plan,
    sigs: &BTreeMap<String, Vec<(String, bool)>>,
) -> Result<BTreeSet<String>, CodegenError> {
    let mut names: BTreeSet<String> = BTreeSet::new();
    for c in plan.called_ops() {
        let sig = sigs
            .get(c)
            .ok_or_else(|| CodegenError::Plan(format!("no shared function `{c}`")))?;
        names.extend(sig.iter().map(|(a, _)| a.clone()));
    }
    names.insert("dt".into());
    names.insert("t0".into());
    if let Some(stop) = &plan.stop {
        // An indicator's slot is a local of the observers already.
        let slot = |n: &str| slots::real(plan).iter().any(|(s, _)| s == n);
        names.extend(
            stop.inputs
                .iter()
                .filter(|n| **n != "t" && !slot(n))
                .map(|n| n.to_string()),
        );
    }
    if plan.observers.stroboscopic() {
        names.insert("strobe_period".into());
        names.insert("strobe_phase".into());
    }
    Ok(names)
}

/// `text` with every non-empty line indented by `n` spaces.
fn indent(text: &str, n: usize) -> String {
    text.lines()
        .map(|l| match l.is_empty() {
            true => "\n".to_string(),
            false => format!("{:n$}{l}\n", ""),
        })
        .collect()
}

/// The pieces of one kernel as they are generated.
struct Gen<'a> {
    plan: &'a Plan,
    /// Does the tangent program move the state (and the step compute
    /// only the time)?
    moves_state: bool,
    /// The plan's Poincaré section (`Plan::section`).
    section: Option<SectionStep>,
    sigs: &'a BTreeMap<String, Vec<(String, bool)>>,
    names: &'a BTreeSet<String>,
    time_table: Option<&'a TimeTable>,
    /// Declarations and loads at the start of the kernel, stores at its end.
    load: String,
    store: String,
}

impl Gen<'_> {
    /// Is the section stroboscopic, sampled exactly at step ends?
    fn exact_section(&self) -> bool {
        self.section
            .as_ref()
            .is_some_and(|s| s.kind == SectionKind::Exact)
    }

    /// The WGSL of an input: a literal for a constant, a table lookup along
    /// its axis otherwise.
    fn input_expr(
        &self,
        src: &Source,
        precision: Precision,
        table: &mut Vec<f64>,
    ) -> Result<String, CodegenError> {
        Ok(match src {
            Source::Const(v) => {
                if precision == Precision::F32 && v.abs() > f32::MAX as f64 {
                    return Err(CodegenError::Plan(format!("{v} does not fit in f32")));
                }
                lit(*v)
            }
            Source::Axis { axis, values } => {
                let off = table.len();
                table.extend(values);
                format!(
                    "table[{off}u + (g / {}u) % {}u]",
                    self.plan.strides[*axis],
                    values.len()
                )
            }
        })
    }

    /// `let` bindings of the inputs the kernel reads (parameters, dt, t0, …).
    fn inputs(&self, precision: Precision, table: &mut Vec<f64>) -> Result<String, CodegenError> {
        let mut inputs = String::new();
        for (name, src) in &self.plan.bindings {
            if self.plan.vars.contains(name) || !self.names.contains(*name) {
                continue;
            }
            // The step and the start time come from the table even when constant,
            // so that the plans of a scene's sub-runs (one per dt) share a kernel.
            let e = match (src, *name) {
                (Source::Const(v), "dt" | "t0") => {
                    table.push(*v);
                    format!("table[{}u]", table.len() - 1)
                }
                _ => self.input_expr(src, precision, table)?,
            };
            writeln!(inputs, "    let {name}: R = {e};").unwrap();
        }
        Ok(inputs)
    }

    /// The integrated variables (initial values at step 0, else the state of
    /// the previous window) and every other name an op binds, as locals.
    fn state(&mut self, precision: Precision, table: &mut Vec<f64>) -> Result<(), CodegenError> {
        let plan = self.plan;
        let mut declared: BTreeSet<&str> = plan
            .bindings
            .iter()
            .filter(|(n, _)| !plan.vars.contains(n) && self.names.contains(*n))
            .map(|(n, _)| *n)
            .collect();
        for (k, v) in plan.vars.iter().enumerate() {
            let init = self.input_expr(plan.binding(v), precision, table)?;
            writeln!(self.load, "    var {v}: R;\n    if u.step0 == 0u {{\n        {v} = {init};\n    }} else {{\n        {v} = state[{k}u * u.cap + i];\n    }}").unwrap();
            writeln!(self.store, "    state[{k}u * u.cap + i] = {v};").unwrap();
            declared.insert(v);
        }
        // Step, time, time terms, derivatives, variables this plan does not integrate.
        for n in self.names {
            if !declared.contains(n.as_str()) {
                writeln!(self.load, "    var {n}: R = 0.0;").unwrap();
            }
        }
        Ok(())
    }

    /// A formula model's values that no step changes, computed once before
    /// the step loop into the locals `fx0…` (`FormulaModel::step_wgsl`).
    fn formula_fixed(&mut self) {
        let Some(sig) = self.sigs.get("formula_fixed") else {
            return;
        };
        for (a, _) in sig.iter().filter(|(_, ptr)| *ptr) {
            writeln!(self.load, "    var {a}: R = 0.0;").unwrap();
        }
        self.load
            .push_str(&self.call("formula_fixed").replacen("        ", "    ", 1));
    }

    /// A call of the shared function `name`, arguments bound by name.
    fn call(&self, name: &str) -> String {
        let args: Vec<String> = self.sigs[name]
            .iter()
            .map(|(a, p)| if *p { format!("&{a}") } else { a.clone() })
            .collect();
        format!("        {name}({});\n", args.join(", "))
    }

    /// One step: the plan's ops (after saving the step's start for interpolation).
    fn step(&self) -> String {
        let mut step = String::new();
        if self.plan.needs_field() {
            for v in &self.plan.vars {
                writeln!(step, "        prev_{v} = {v};\n        dprev_{v} = d{v};").unwrap();
            }
        } else if self.plan.indicators.is_some() {
            for v in &self.plan.vars {
                writeln!(step, "        prev_{v} = {v};").unwrap();
            }
        }
        if let Some(tt) = self.time_table {
            let stride = tt.row_stride();
            writeln!(step, "        let trow = (n - u.step0) * {stride}u;").unwrap();
        }
        // A formula model's whole step is one function (`shared_text`),
        // its shared values arguments.
        if self.sigs.contains_key("formula_step") {
            if let Some(tt) = self.time_table {
                step.push_str(&Self::table_reads(tt, 0, "let ", ": R"));
            }
            step.push_str(&self.call("formula_step"));
            return step;
        }
        let mut stage = 0;
        for op in &self.plan.ops {
            match op {
                // The tangent program moves the state (below); `t` as the
                // ops leave it is for the observers.
                Op::Tau(_) | Op::Call(_) if self.moves_state => {}
                Op::Tau(c) => writeln!(step, "        tau = {} * dt;", lit(*c)).unwrap(),
                Op::Time(c) => {
                    writeln!(step, "        t = t0 + nf * dt + {} * dt;", lit(*c)).unwrap();
                    if let Some(tt) = self.time_table {
                        step.push_str(&Self::table_reads(tt, stage, "", ""));
                    }
                    stage += 1;
                }
                // Read from the table above instead.
                Op::Call(name) if self.time_table.is_some_and(|tt| tt.ops().contains(name)) => {}
                Op::Call(name) => step.push_str(&self.call(name)),
            }
        }
        if self.moves_state {
            step.push_str(&self.tangent_call());
        }
        step
    }

    /// The call of the tangent program, after the locals it reads from
    /// this window's table of time terms where it has one.
    fn tangent_call(&self) -> String {
        let mut s = String::new();
        if let Some(tt) = self.time_table.filter(|tt| !tt.ops().is_empty()) {
            s.push_str(&Self::table_terms(tt));
        }
        s + &self.call("tangent_step")
    }

    /// Every time term of every stage of the step from this window's
    /// table, as the locals of [`table_term`], for the tangent program.
    fn table_terms(tt: &TimeTable) -> String {
        let mut s = String::new();
        for stage in 0..tt.stages() {
            for term in 0..tt.terms.len() {
                let at = stage * tt.vec4s() + term / 4;
                let name = table_term(stage, term);
                writeln!(
                    s,
                    "        let {name}: R = tterms[trow + {at}u][{}];",
                    term % 4
                )
                .unwrap();
            }
        }
        s
    }

    /// The time terms of stage `stage` from this window's table, assigned
    /// to existing locals (`decl`, `ty` empty) or declared (`let `, `: R`).
    fn table_reads(tt: &TimeTable, stage: usize, decl: &str, ty: &str) -> String {
        let first = stage * tt.vec4s();
        tt.terms
            .iter()
            .enumerate()
            .map(|(j, term)| {
                format!(
                    "        {decl}{term}{ty} = tterms[trow + {}u][{}];\n",
                    first + j / 4,
                    j % 4
                )
            })
            .collect()
    }

    /// The vector field at step `n1` into the `d<var>` locals.
    fn field(&self, n1: &str) -> String {
        let mut s = if self.names.contains("t") {
            format!("        t = t0 + R({n1}) * dt;\n")
        } else {
            String::new()
        };
        for f in &self.plan.field_ops {
            s.push_str(&self.call(f));
        }
        s
    }

    /// Observer code: at the start of the kernel (state kept in `aux_*`, the
    /// field and observations of step 0) and after every step.
    fn observers(&mut self) -> (String, String) {
        let plan = self.plan;
        let mut begin = String::new();
        let mut observe = String::new();
        if plan.has_slots() {
            self.aux_state();
            let sample = self.window_sample();
            self.store.insert_str(0, &sample);
        }
        if plan.needs_field() {
            for v in &plan.vars {
                writeln!(
                    self.load,
                    "    var prev_{v}: R = 0.0;\n    var dprev_{v}: R = 0.0;"
                )
                .unwrap();
            }
            begin.push_str(&self.field("u.step0"));
            observe.push_str(&self.field("n + 1u"));
        } else if plan.indicators.is_some() {
            for v in &plan.vars {
                writeln!(self.load, "    var prev_{v}: R = 0.0;").unwrap();
            }
        }
        let o = &plan.observers;
        if o.trajectory.is_some() || o.poincare.is_some() || o.attractors.is_some() {
            let mut initial = self.observe_at("0u", true);
            initial.push_str(&self.indicator_frame("0u"));
            writeln!(begin, "    if u.step0 == 0u {{\n{initial}    }}").unwrap();
        }
        observe.push_str(&self.observe_at("n + 1u", false));
        observe.push_str(&self.cycle());
        observe.push_str(&self.average());
        observe.push_str(&self.indicators());
        observe.push_str(&self.indicator_frame("n + 1u"));
        observe.push_str(&self.stop());
        (begin, observe)
    }

    /// Observer state that lives across dispatches, loaded and stored.
    fn aux_state(&mut self) {
        for (k, (a, init)) in slots::real(self.plan).iter().enumerate() {
            let init = init.wgsl();
            writeln!(self.load, "    var {a}: R = {init};\n    if u.step0 != 0u {{\n        {a} = aux_r[{k}u * u.cap + i];\n    }}").unwrap();
            writeln!(self.store, "    aux_r[{k}u * u.cap + i] = {a};").unwrap();
        }
        // Counters are i32 in the shared functions, u32 in the buffer.
        for (k, a) in slots::COUNT.iter().enumerate() {
            writeln!(self.load, "    var {a}: i32 = 0;\n    if u.step0 != 0u {{\n        {a} = i32(aux_u[{k}u * u.cap + i]);\n    }}").unwrap();
            writeln!(self.store, "    aux_u[{k}u * u.cap + i] = u32({a});").unwrap();
        }
        if self.exact_section() {
            self.load.push_str("    var strobe_every: i32 = 0;\n    var strobe_first: i32 = 0;\n    strobe_exact_steps(strobe_period, strobe_phase, dt, &strobe_every, &strobe_first);\n");
        }
    }

    /// An observed variable at θ inside the step that ends at `n1` (the
    /// state itself at the step's end, where a section never interpolates).
    fn value(&self, v: &ObsVar, th: &str, n1: &str, interpolates: bool) -> String {
        match v {
            ObsVar::Time => format!("observed_time(t0, R({n1}), dt, {th})"),
            ObsVar::State(k) => {
                let x = self.plan.vars[*k];
                if interpolates {
                    format!("observed_state(prev_{x}, {x}, dprev_{x}, d{x}, dt, {th})")
                } else {
                    x.to_string()
                }
            }
        }
    }

    /// Trajectory frames and Poincaré points after step `n1`.
    fn observe_at(&self, n1: &str, initial: bool) -> String {
        let mut s = self.frame(n1);
        if let Some(section) = &self.section {
            s.push_str(&self.section(section, n1, initial));
        }
        if initial {
            s.push_str(&self.attractor_sample(n1, "true"));
        }
        s
    }

    /// The attractor detector's sample after step `n1` where one is due
    /// (without a section: every `every` steps after the skipped part) and
    /// `running` holds. After step 0 in the kernel's beginning; the others
    /// at the end of a window, which ends at each ([`Self::window_sample`]).
    fn attractor_sample(&self, n1: &str, running: &str) -> String {
        let Some(at) = slots::recurrence(self.plan) else {
            return String::new();
        };
        let Some(every) = at.every else {
            return String::new();
        };
        let take = indent(&self.take_sample(&self.sampled(n1, "1.0", false)), 4);
        let due = format!(
            "{running} && ({n1}) >= {}u && ({n1}) % {every}u == 0u",
            at.skip_step
        );
        indent(&format!("if {due} {{\n{take}}}\n"), 8)
    }

    /// The sample after the window's last step, for a trajectory still
    /// running or stopped after that step (a stop after a sample's step
    /// comes after its sample, as on the CPU). Taken outside the step loop:
    /// llvmpipe runs an `if` inside it at every step, under a mask.
    fn window_sample(&self) -> String {
        let end = "(u.step0 + u.nsteps)";
        let running = format!("(st == 0u || st == ({}u | {end}))", slots::STOPPED);
        self.attractor_sample(end, &running)
    }

    /// The attractor detector's sampled components at θ = `th` inside the
    /// step that ends at `n1`, as WGSL expressions.
    fn sampled(&self, n1: &str, th: &str, interpolates: bool) -> Vec<String> {
        (self.plan.attractor_vars.iter())
            .map(|v| self.value(v, th, n1, interpolates))
            .collect()
    }

    /// Takes a sample of `values` (a WGSL expression per component) into
    /// the attractor detector, as `cpu::observe::take_sample` does.
    fn take_sample(&self, values: &[String]) -> String {
        let (Some(at), names) = (slots::recurrence(self.plan), slots::real(self.plan)) else {
            return String::new();
        };
        let name = |k: usize| names[k].0.as_str();
        let mut s = String::from("{\n");
        for (c, v) in values.iter().enumerate() {
            writeln!(s, "    let rx{c}: R = {v};").unwrap();
        }
        s.push_str("    var gap: R = 0.0;\n");
        for k in 1..=at.max_period {
            s.push_str("    gap = 0.0;\n");
            for c in 0..at.dim {
                let (y, wrap) = (name(at.sample(k, c)), lit(at.wrap[c]));
                writeln!(s, "    gap = recurrence_gap(rx{c}, {y}, {wrap}, gap);").unwrap();
            }
            let (tol, n, held) = (lit(at.tolerance), name(at.count()), name(at.held(k)));
            writeln!(
                s,
                "    recurrence_held(gap, {tol}, {}, {n}, &{held});",
                lit(k as f64)
            )
            .unwrap();
        }
        for j in (2..=at.max_period).rev() {
            for c in 0..at.dim {
                let (to, from) = (name(at.sample(j, c)), name(at.sample(j - 1, c)));
                writeln!(s, "    {to} = {from};").unwrap();
            }
        }
        for c in 0..at.dim {
            writeln!(s, "    {} = rx{c};", name(at.sample(1, c))).unwrap();
        }
        writeln!(s, "    {n} = {n} + 1.0;\n}}", n = name(at.count())).unwrap();
        s
    }

    /// A trajectory frame, if step `n1` is one.
    fn frame(&self, n1: &str) -> String {
        let Some(tr) = &self.plan.observers.trajectory else {
            return String::new();
        };
        let values = self
            .plan
            .trajectory_vars
            .iter()
            .map(|v| self.value(v, "1.0", n1, false));
        self.frame_writes(tr.every, n1, 0, values)
    }

    /// The indicators' slots that make their running values, if step `n1`
    /// is a trajectory frame (after the frame's state in `traj_out`).
    fn indicator_frame(&self, n1: &str) -> String {
        let (Some(tr), Some(_)) = (&self.plan.observers.trajectory, &self.plan.indicators) else {
            return String::new();
        };
        let names = slots::real(self.plan);
        let values = slots::indicator_frame_slots(self.plan)
            .into_iter()
            .map(|k| names[k].0.clone());
        self.frame_writes(tr.every, n1, self.plan.trajectory_vars.len(), values)
    }

    /// `values` as a trajectory frame's values `first…` if step `n1` is one.
    fn frame_writes(
        &self,
        every: u64,
        n1: &str,
        first: usize,
        values: impl Iterator<Item = String>,
    ) -> String {
        let width = frame_width(self.plan);
        let mut s = format!(
            "        if frame_due(i32({n1}), {every}) {{\n            let fr = ({n1}) / {every}u - u.frame0;\n"
        );
        for (j, value) in values.enumerate() {
            let j = first + j;
            writeln!(
                s,
                "            traj_out[(fr * {width}u + {j}u) * u.cap + i] = {value};"
            )
            .unwrap();
        }
        s.push_str("        }\n");
        s
    }

    /// The section's points in the step that ends at `n1`, as the shared
    /// `section_next` finds them, each stored as point number `npoints` if
    /// kept (`point_kept`).
    fn section(&self, section: &SectionStep, n1: &str, initial: bool) -> String {
        let zero = "0.0".to_string();
        let (every, first) = match section.kind {
            SectionKind::Exact => ("strobe_every", "strobe_first"),
            _ => ("0", "0"),
        };
        let (period, phase) = match section.kind {
            SectionKind::Crossing { .. } => (zero.clone(), zero.clone()),
            _ => ("strobe_period".into(), "strobe_phase".into()),
        };
        let ([y0, y1, d0, d1], direction) = match section.kind {
            SectionKind::Crossing {
                var,
                level,
                direction,
            } => {
                let (x, l) = (self.plan.vars[var], lit(level));
                let ends = [
                    format!("prev_{x} - {l}"),
                    format!("{x} - {l}"),
                    format!("dprev_{x}"),
                    format!("d{x}"),
                ];
                (ends, direction.code())
            }
            _ => ([zero.clone(), zero.clone(), zero.clone(), zero], 0),
        };
        let next = format!(
            "section_next({kind}, i32({n1}), {initial}, {every}, {first}, {period}, {phase}, dt, {y0}, {y1}, {d0}, {d1}, {direction}, &strobe_k, &done, &th)",
            kind = section.kind.code(),
        );
        let npv = section.columns.len();
        let mut record = format!(
            "let slot = u32(npoints);\nif point_kept(&npoints, {}) {{\n",
            section.kept_limit()
        );
        for (j, c) in section.columns.iter().enumerate() {
            let x = match c {
                Recorded::Level(level) => lit(*level),
                Recorded::Var(v) => self.value(v, "th", n1, section.kind.interpolates()),
            };
            writeln!(
                record,
                "    points_out[(slot * {npv}u + {j}u) * u.cap + i] = {x};"
            )
            .unwrap();
        }
        record.push_str("}\n");
        if let Some(at) = slots::recurrence(self.plan) {
            let values = self.sampled(n1, "th", section.kind.interpolates());
            let take = indent(&self.take_sample(&values), 4);
            write!(record, "if ({n1}) >= {}u {{\n{take}}}\n", at.skip_step).unwrap();
        }
        // Every loop iteration counts against llvmpipe's limit
        // ([`LOOP_ITERATIONS`]): a loop only where a step may hold several
        // points, entered only after a first one.
        let mut body = record.clone();
        if section.max_per_step > 1 {
            let again = format!("if !{next} {{\n    break;\n}}\n{record}");
            write!(body, "loop {{\n{}}}\n", indent(&again, 4)).unwrap();
        }
        let block = format!(
            "{{\n    var done = false;\n    var th: R = 1.0;\n    if {next} {{\n{}    }}\n}}\n",
            indent(&body, 8)
        );
        indent(&block, 8)
    }

    /// Cycle statistics over the step, inside the measuring window.
    fn cycle(&self) -> String {
        let plan = self.plan;
        let (Some(k), Some(cy)) = (plan.cycle_var, &plan.observers.cycle) else {
            return String::new();
        };
        let x = plan.vars[k];
        let start = plan.cycle_start();
        format!(
            "        if n + 1u >= {start}u {{\n            cycle_step({x}, prev_{x} - {l}, {x} - {l}, dprev_{x}, d{x}, dt, t0 + nf * dt, &cyc_max, &cyc_min, &cyc_count, &cyc_first, &cyc_mean, &cyc_com);\n        }}\n",
            l = lit(cy.level)
        )
    }

    /// Time averages over the step, after the skipped part of the run.
    fn average(&self) -> String {
        let plan = self.plan;
        let start = plan.average_start();
        let mut s = String::new();
        for (j, v) in plan.average_vars.iter().enumerate() {
            let ObsVar::State(k) = v else {
                unreachable!("time is not averaged")
            };
            let x = plan.vars[*k];
            writeln!(
                s,
                "        if n + 1u > {start}u {{\n            mean_step({x}, R(n + 1u - {start}u), &mean_{j});\n        }}"
            )
            .unwrap();
        }
        s
    }

    /// The chaos indicators after the step: the deviation vectors through
    /// the tangent map, then the samples due. A vector that leaves the
    /// finite numbers stays out of them and loses its trajectory's
    /// indicators (`slots::indicators_finish`), never its state.
    fn indicators(&self) -> String {
        let Some(ind) = &self.plan.indicators else {
            return String::new();
        };
        let mut s = match self.moves_state {
            true => String::new(),
            false => self.tangent_call(),
        };
        // Only MEGNO's running mean reads 1/n: where the FLI is sampled
        // without it, its slot is never read and the division per
        // trajectory and sample goes (lavapipe, spin–orbit FLI f64: 0.93×
        // the time, median of 4 pairs).
        let inv_count = match self.plan.observers.megno {
            Some(_) => "R(1.0) / count",
            None => "R(0.0)",
        };
        for (name, smp) in ind.samplers() {
            let every = smp.every;
            writeln!(
                s,
                "        if (n + 1u) % {every}u == 0u {{\n            let count: R = R((n + 1u) / {every}u);\n            let inv_count: R = {inv_count};\n            let at_skip: R = select(R(0.0), R(1.0), n + 1u == {}u);\n    {}        }}",
                ind.skip_step,
                self.call(name)
            )
            .unwrap();
        }
        s
    }

    /// The stop condition after the step: the thread leaves its loop,
    /// its state the stop's (observers have seen the step).
    fn stop(&self) -> String {
        let Some(stop) = &self.plan.stop else {
            return String::new();
        };
        format!(
            "        {{\n            let stop_t: R = t0 + R(n + 1u) * dt;\n            var stop_g: R = 0.0;\n    {}            if {} {{\n                st = {}u | (n + 1u);\n                break;\n            }}\n        }}\n",
            self.call("stop_value"),
            stop.cmp.wgsl("stop_g"),
            slots::STOPPED
        )
    }
}
