//! High-accuracy adaptive reference integrator: DOP853 with dense output.
//!
//! This is the explicit Runge–Kutta method of order 8 of Dormand and Prince with
//! the combined 5th/3rd-order error estimator and the 7th-order continuous
//! extension, as described by Hairer, Nørsett & Wanner ("Solving Ordinary
//! Differential Equations I", Sec. II.10) and implemented in Fortran `dop853.f`
//! and in `scipy.integrate.DOP853`.
//!
//! The step-size controller, error norm and initial-step heuristic follow
//! scipy's implementation (`scipy/integrate/_ivp/rk.py`, class `DOP853`, and
//! `select_initial_step` in `scipy/integrate/_ivp/common.py`, scipy 1.17.1)
//! line by line, so that runs are directly comparable with
//! `solve_ivp(..., method="DOP853")`.
//!
//! It is meant as a trusted reference to validate other integrators against,
//! so it favours fidelity to the published method over speed.

use std::fmt;

// ---------------------------------------------------------------------------
// Coefficients.
//
// Source: scipy 1.17.1, file `scipy/integrate/_ivp/dop853_coefficients.py`
// (installed from PyPI). The literals below are Python `repr` of the f64
// values of scipy's arrays (round-trip exact, hence bit-identical to scipy's
// tableau). `A` is stored row by row as its strictly lower triangle; rows 0..12
// are the main method (row 12 holds the weights `B`, i.e. the FSAL stage
// `f(t + h, y_new)`), rows 13..16 are the three extra stages used only by the
// dense output. `E3` is scipy's `B - [0.244094488188976377952755905512 at 0,
// 0.733846688281611857341361741547 at 8, 0.0220588235294117647058823529412 at 11]`
// evaluated in f64 (checked exactly in the tests). `E3`/`E5` have a 13th entry
// (for the FSAL stage) which is zero in scipy and is therefore omitted.
// `D` gives the last four coefficients of the 7th-order interpolant.
// ---------------------------------------------------------------------------

/// Number of stages of the main method (excluding the FSAL stage).
const N_STAGES: usize = 12;
/// Number of stages including the FSAL stage and the three dense-output stages.
const N_STAGES_EXTENDED: usize = 16;
/// Number of polynomial coefficient vectors of the continuous extension.
const INTERPOLATOR_POWER: usize = 7;

const C: [f64; 16] = [
    0.0,
    0.05260015195876773,
    0.0789002279381516,
    0.1183503419072274,
    0.2816496580927726,
    0.3333333333333333,
    0.25,
    0.3076923076923077,
    0.6512820512820513,
    0.6,
    0.8571428571428571,
    1.0,
    1.0,
    0.1,
    0.2,
    0.7777777777777778,
];

#[rustfmt::skip]
const A: [&[f64]; 16] = [
    &[],
    &[0.05260015195876773],
    &[0.0197250569845379, 0.0591751709536137],
    &[0.02958758547680685, 0.0, 0.08876275643042054],
    &[0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792],
    &[0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242],
    &[0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125],
    &[0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.008273789163814023],
    &[0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671, 20.154067550477894, -43.48988418106996],
    &[0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193, 15.279233632882423, -33.28821096898486, -0.020331201708508627],
    &[-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927, -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196],
    &[2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636],
    &[0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259],
    &[0.056167502283047954, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25350021021662483, -0.2462390374708025, -0.12419142326381637, 0.15329179827876568, 0.00820105229563469, 0.007567897660545699, -0.008298],
    &[0.03183464816350214, 0.0, 0.0, 0.0, 0.0, 0.028300909672366776, 0.053541988307438566, -0.05492374857139099, 0.0, 0.0, -0.00010834732869724932, 0.0003825710908356584, -0.00034046500868740456, 0.1413124436746325],
    &[-0.42889630158379194, 0.0, 0.0, 0.0, 0.0, -4.697621415361164, 7.683421196062599, 4.06898981839711, 0.3567271874552811, 0.0, 0.0, 0.0, -0.0013990241651590145, 2.9475147891527724, -9.15095847217987],
];

const B: [f64; 12] = [
    0.054293734116568765,
    0.0,
    0.0,
    0.0,
    0.0,
    4.450312892752409,
    1.8915178993145003,
    -5.801203960010585,
    0.3111643669578199,
    -0.1521609496625161,
    0.20136540080403034,
    0.04471061572777259,
];

const E3: [f64; 12] = [
    -0.18980075407240762,
    0.0,
    0.0,
    0.0,
    0.0,
    4.450312892752409,
    1.8915178993145003,
    -5.801203960010585,
    -0.4226823213237919,
    -0.1521609496625161,
    0.20136540080403034,
    0.02265179219836082,
];

const E5: [f64; 12] = [
    0.01312004499419488,
    0.0,
    0.0,
    0.0,
    0.0,
    -1.2251564463762044,
    -0.4957589496572502,
    1.6643771824549864,
    -0.35032884874997366,
    0.3341791187130175,
    0.08192320648511571,
    -0.022355307863886294,
];

#[rustfmt::skip]
const D: [[f64; 16]; 4] = [
    [-8.428938276109013, 0.0, 0.0, 0.0, 0.0, 0.5667149535193777, -3.0689499459498917, 2.38466765651207, 2.117034582445028, -0.871391583777973, 2.2404374302607883, 0.6315787787694688, -0.08899033645133331, 18.148505520854727, -9.194632392478356, -4.436036387594894],
    [10.427508642579134, 0.0, 0.0, 0.0, 0.0, 242.28349177525817, 165.20045171727028, -374.5467547226902, -22.113666853125306, 7.733432668472264, -30.674084731089398, -9.332130526430229, 15.697238121770845, -31.139403219565178, -9.35292435884448, 35.81684148639408],
    [19.985053242002433, 0.0, 0.0, 0.0, 0.0, -387.0373087493518, -189.17813819516758, 527.8081592054236, -11.57390253995963, 6.8812326946963, -1.0006050966910838, 0.7777137798053443, -2.778205752353508, -60.19669523126412, 84.32040550667716, 11.99229113618279],
    [-25.69393346270375, 0.0, 0.0, 0.0, 0.0, -154.18974869023643, -231.5293791760455, 357.6391179106141, 93.40532418362432, -37.45832313645163, 104.0996495089623, 29.8402934266605, -43.53345659001114, 96.32455395918828, -39.17726167561544, -149.72683625798564],
];

/// Multiplies the asymptotically optimal step factor (scipy's `SAFETY`).
const SAFETY: f64 = 0.9;
/// Smallest allowed step-size decrease factor (scipy's `MIN_FACTOR`).
const MIN_FACTOR: f64 = 0.2;
/// Largest allowed step-size increase factor (scipy's `MAX_FACTOR`).
const MAX_FACTOR: f64 = 10.0;
/// Order of the error estimator; the controlled error behaves like `h^8`.
const ERROR_ESTIMATOR_ORDER: i32 = 7;
/// Exponent of the step-size controller, `-1 / (error_estimator_order + 1)`.
const ERROR_EXPONENT: f64 = -1.0 / (ERROR_ESTIMATOR_ORDER as f64 + 1.0);

/// Options of the adaptive integration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dop853Options {
    /// Relative tolerance. Values below `100 * f64::EPSILON` are raised to it
    /// (as scipy does), because tighter requests cannot be met in f64.
    pub rtol: f64,
    /// Absolute tolerance (must be `>= 0`; `rtol` and `atol` cannot both be 0).
    /// With `atol == 0` a component that is exactly zero at both ends of a step
    /// has a zero error scale, which makes the step fail (as in scipy); keep
    /// `atol > 0` unless all components stay away from zero.
    pub atol: f64,
    /// First step size; `None` selects it automatically with scipy's
    /// `select_initial_step` heuristic (costs one evaluation of `f`).
    pub h_initial: Option<f64>,
    /// Largest allowed step size (`f64::INFINITY` for no limit).
    pub h_max: f64,
    /// Largest number of attempted steps (accepted plus rejected), as `NMAX`
    /// in `dop853.f`; exceeding it returns [`Dop853Error::TooManySteps`].
    pub max_steps: u64,
}

impl Default for Dop853Options {
    /// Tight defaults, since this integrator serves as a reference solution.
    fn default() -> Self {
        Self {
            rtol: 1e-12,
            atol: 1e-14,
            h_initial: None,
            h_max: f64::INFINITY,
            max_steps: 10_000_000,
        }
    }
}

/// Statistics of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Dop853Stats {
    /// Accepted steps.
    pub steps: u64,
    /// Rejected step attempts.
    pub rejected: u64,
    /// Calls of the right-hand side `f`, all included (initial derivative,
    /// initial-step selection, 12 per attempted step, 3 per dense-output
    /// construction).
    pub evaluations: u64,
}

/// Failure of [`dop853`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Dop853Error {
    /// The step size fell below ten ulps of `t` (e.g. near a singularity).
    StepTooSmall {
        /// Time reached.
        t: f64,
    },
    /// More than [`Dop853Options::max_steps`] step attempts were needed.
    TooManySteps {
        /// Time reached.
        t: f64,
    },
    /// The state (or its derivative) became non-finite and no step size,
    /// however small, avoided it; or the initial data were non-finite.
    NonFinite {
        /// Time reached.
        t: f64,
    },
    /// Arguments violating the documented preconditions (unsorted or
    /// non-finite `times`, a time before `t0`, invalid tolerances, ...).
    InvalidInput {
        /// What was wrong.
        reason: &'static str,
    },
}

impl fmt::Display for Dop853Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::StepTooSmall { t } => write!(f, "DOP853: step size too small at t = {t}"),
            Self::TooManySteps { t } => {
                write!(f, "DOP853: maximum number of steps exceeded at t = {t}")
            }
            Self::NonFinite { t } => write!(f, "DOP853: non-finite state at t = {t}"),
            Self::InvalidInput { reason } => write!(f, "DOP853: invalid input: {reason}"),
        }
    }
}

impl std::error::Error for Dop853Error {}

/// Stage storage: `k[s]` is the derivative at stage `s`. `k[0]` is `f(t, y)`,
/// `k[12]` is `f(t + h, y_new)` (first same as last), `k[13..16]` are the
/// dense-output stages.
type Stages = [Vec<f64>; N_STAGES_EXTENDED];

/// Root-mean-square norm, as scipy's `common.norm`.
fn rms_norm(v: impl Iterator<Item = f64>, n: usize) -> f64 {
    let sum: f64 = v.map(|x| x * x).sum();
    (sum / n as f64).sqrt()
}

/// Smallest f64 strictly greater than finite `t` (equivalent of
/// `f64::next_up`, written out to avoid depending on a recent toolchain).
fn next_up(t: f64) -> f64 {
    if t.is_nan() || t == f64::INFINITY {
        return t;
    }
    if t == 0.0 {
        return f64::from_bits(1);
    }
    let bits = t.to_bits();
    if t > 0.0 {
        f64::from_bits(bits + 1)
    } else {
        f64::from_bits(bits - 1)
    }
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Sets `out = y + h * sum_j a[j] * k[j]` (the argument of a stage).
fn stage_argument(out: &mut [f64], y: &[f64], h: f64, a: &[f64], k: &Stages) {
    for (i, (o, &yi)) in out.iter_mut().zip(y).enumerate() {
        let mut acc = 0.0;
        for (&aj, kj) in a.iter().zip(k.iter()) {
            if aj != 0.0 {
                acc += aj * kj[i];
            }
        }
        *o = yi + h * acc;
    }
}

/// One step of the main method (scipy's `rk_step`): given `k[0] = f(t, y)`,
/// fills `k[1..=12]` and `y_new`. Costs 12 evaluations of `f`.
fn rk_step<F: FnMut(f64, &[f64], &mut [f64])>(
    f: &mut F,
    t: f64,
    y: &[f64],
    h: f64,
    k: &mut Stages,
    ytmp: &mut [f64],
    y_new: &mut [f64],
) {
    for s in 1..N_STAGES {
        stage_argument(ytmp, y, h, A[s], k);
        f(t + C[s] * h, ytmp, &mut k[s]);
    }
    stage_argument(y_new, y, h, &B, k);
    f(t + h, y_new, &mut k[N_STAGES]);
}

/// scipy's `DOP853._estimate_error_norm`: the 5th-order estimate `err5`
/// damped by the 3rd-order estimate `err3` as in `dop853.f`,
/// `|h| * |err5|^2 / sqrt(n * (|err5|^2 + 0.01 |err3|^2))`, with the
/// componentwise scale `atol + rtol * max(|y|, |y_new|)`.
fn error_norm(k: &Stages, h: f64, y: &[f64], y_new: &[f64], rtol: f64, atol: f64) -> f64 {
    let mut err5_sq = 0.0;
    let mut err3_sq = 0.0;
    for (i, (&yo, &yn)) in y.iter().zip(y_new).enumerate() {
        let scale = atol + yo.abs().max(yn.abs()) * rtol;
        let mut e5 = 0.0;
        let mut e3 = 0.0;
        for (s, ks) in k.iter().take(N_STAGES).enumerate() {
            e5 += E5[s] * ks[i];
            e3 += E3[s] * ks[i];
        }
        let (e5, e3) = (e5 / scale, e3 / scale);
        err5_sq += e5 * e5;
        err3_sq += e3 * e3;
    }
    if err5_sq == 0.0 && err3_sq == 0.0 {
        return 0.0;
    }
    let denom = err5_sq + 0.01 * err3_sq;
    h.abs() * err5_sq / (denom * y.len() as f64).sqrt()
}

/// Coefficients of the 7th-order continuous extension on one accepted step
/// (scipy's `DOP853._dense_output_impl`). Computing them costs the three extra
/// stages `k[13..16]`, hence 3 evaluations of `f`.
struct DenseStep {
    t_old: f64,
    h: f64,
    /// `F[0..7]` of scipy, one vector per coefficient.
    coef: [Vec<f64>; INTERPOLATOR_POWER],
}

impl DenseStep {
    fn new(n: usize) -> Self {
        Self {
            t_old: 0.0,
            h: 0.0,
            coef: std::array::from_fn(|_| vec![0.0; n]),
        }
    }

    /// Builds the interpolant of the step `t_old -> t_old + h`, `y_old -> y_new`,
    /// with the main stages in `k[0..=12]`; fills `k[13..16]`.
    #[allow(clippy::too_many_arguments)]
    fn build<F: FnMut(f64, &[f64], &mut [f64])>(
        &mut self,
        f: &mut F,
        t_old: f64,
        h: f64,
        y_old: &[f64],
        y_new: &[f64],
        k: &mut Stages,
        ytmp: &mut [f64],
    ) {
        for s in N_STAGES + 1..N_STAGES_EXTENDED {
            stage_argument(ytmp, y_old, h, A[s], k);
            f(t_old + C[s] * h, ytmp, &mut k[s]);
        }
        self.t_old = t_old;
        self.h = h;
        let f_old = &k[0];
        let f_new = &k[N_STAGES];
        for i in 0..y_old.len() {
            let dy = y_new[i] - y_old[i];
            self.coef[0][i] = dy;
            self.coef[1][i] = h * f_old[i] - dy;
            self.coef[2][i] = 2.0 * dy - h * (f_new[i] + f_old[i]);
            for (r, d) in D.iter().enumerate() {
                let acc: f64 = d.iter().zip(k.iter()).map(|(&dj, kj)| dj * kj[i]).sum();
                self.coef[3 + r][i] = h * acc;
            }
        }
    }

    /// Evaluates the interpolant at `t` into `out` (scipy's
    /// `Dop853DenseOutput._call_impl`: nested multiplication alternating the
    /// factors `x` and `1 - x`, with `x = (t - t_old) / h`).
    fn eval(&self, t: f64, y_old: &[f64], out: &mut [f64]) {
        let x = (t - self.t_old) / self.h;
        for (i, (o, &yo)) in out.iter_mut().zip(y_old).enumerate() {
            let mut acc = 0.0;
            for (j, c) in self.coef.iter().rev().enumerate() {
                acc += c[i];
                acc *= if j % 2 == 0 { x } else { 1.0 - x };
            }
            *o = acc + yo;
        }
    }
}

/// scipy's `select_initial_step` (Hairer–Nørsett–Wanner, Sec. II.4): a first
/// step size from the scaled sizes of `y0`, `f0` and a finite-difference
/// estimate of the second derivative. Costs one evaluation of `f`.
#[allow(clippy::too_many_arguments)]
fn select_initial_step<F: FnMut(f64, &[f64], &mut [f64])>(
    f: &mut F,
    t0: f64,
    y0: &[f64],
    f0: &[f64],
    t_bound: f64,
    h_max: f64,
    rtol: f64,
    atol: f64,
) -> f64 {
    let n = y0.len();
    let interval_length = (t_bound - t0).abs();
    if interval_length == 0.0 {
        return 0.0;
    }
    let scale: Vec<f64> = y0.iter().map(|y| atol + y.abs() * rtol).collect();
    let d0 = rms_norm(y0.iter().zip(&scale).map(|(y, s)| y / s), n);
    let d1 = rms_norm(f0.iter().zip(&scale).map(|(y, s)| y / s), n);
    let h0 = if d0 < 1e-5 || d1 < 1e-5 {
        1e-6
    } else {
        0.01 * d0 / d1
    };
    let h0 = h0.min(interval_length);
    let y1: Vec<f64> = y0.iter().zip(f0).map(|(y, fy)| y + h0 * fy).collect();
    let mut f1 = vec![0.0; n];
    f(t0 + h0, &y1, &mut f1);
    let d2 = rms_norm(
        f1.iter().zip(f0).zip(&scale).map(|((a, b), s)| (a - b) / s),
        n,
    ) / h0;
    let h1 = if d1 <= 1e-15 && d2 <= 1e-15 {
        (h0 * 1e-3).max(1e-6)
    } else {
        // f64::max ignores a NaN `d2` (as Python's `max` does here).
        (0.01 / d1.max(d2)).powf(1.0 / (f64::from(ERROR_ESTIMATOR_ORDER) + 1.0))
    };
    (100.0 * h0).min(h1).min(interval_length).min(h_max)
}

/// Checks the documented preconditions of [`dop853`].
fn validate(t0: f64, times: &[f64], opts: &Dop853Options) -> Result<(), Dop853Error> {
    let bad = |reason| Err(Dop853Error::InvalidInput { reason });
    if !t0.is_finite() {
        return bad("t0 must be finite");
    }
    if times.iter().any(|t| !t.is_finite()) {
        return bad("output times must be finite");
    }
    if times.first().is_some_and(|&t| t < t0) {
        return bad("output times must be >= t0");
    }
    if times.windows(2).any(|w| w[1] < w[0]) {
        return bad("output times must be sorted ascending");
    }
    if !(opts.rtol >= 0.0 && opts.rtol.is_finite() && opts.atol >= 0.0 && opts.atol.is_finite()) {
        return bad("rtol and atol must be finite and >= 0");
    }
    if opts.rtol == 0.0 && opts.atol == 0.0 {
        return bad("rtol and atol cannot both be zero");
    }
    if opts.h_max.is_nan() || opts.h_max <= 0.0 {
        return bad("h_max must be > 0");
    }
    if let Some(h) = opts.h_initial {
        if !(h > 0.0 && h.is_finite()) {
            return bad("h_initial must be finite and > 0");
        }
    }
    Ok(())
}

/// Integrates `y' = f(t, y)` from `t0` to the last of `times` (sorted
/// ascending, all `>= t0`; may include `t0` and repeated values), returning the
/// state at every requested time and the statistics.
///
/// `f(t, y, dy)` writes the derivative into `dy`. Works for any dimension
/// (`y0.len() == 0` gives empty states without calling `f`).
///
/// The integration lands exactly on the last time. Requested times that fall
/// inside an accepted step are served by the 7th-order continuous extension
/// (three extra evaluations, made only for steps that contain such a time), so
/// dense outputs do not shorten the steps; times hitting a step end exactly
/// get the step's state.
///
/// # Errors
///
/// [`Dop853Error::StepTooSmall`] when the step size falls below ten ulps of
/// `t`, [`Dop853Error::NonFinite`] when the state cannot be kept finite,
/// [`Dop853Error::TooManySteps`] after `opts.max_steps` attempts, and
/// [`Dop853Error::InvalidInput`] for violated preconditions.
pub fn dop853<F: FnMut(f64, &[f64], &mut [f64])>(
    mut f: F,
    t0: f64,
    y0: &[f64],
    times: &[f64],
    opts: &Dop853Options,
) -> Result<(Vec<Vec<f64>>, Dop853Stats), Dop853Error> {
    validate(t0, times, opts)?;
    let mut out = Vec::with_capacity(times.len());
    if y0.is_empty() {
        out.resize(times.len(), Vec::new());
        return Ok((out, Dop853Stats::default()));
    }
    if !all_finite(y0) {
        return Err(Dop853Error::NonFinite { t: t0 });
    }
    // Outputs requested at t0 itself are exactly y0.
    let mut next = times.iter().take_while(|&&t| t == t0).count();
    out.resize(next, y0.to_vec());
    let Some(&t_end) = times.last() else {
        return Ok((out, Dop853Stats::default()));
    };
    if next == times.len() {
        return Ok((out, Dop853Stats::default()));
    }

    let mut run = Run::start(&mut f, t0, y0, t_end, opts)?;
    while run.t < t_end {
        let (t_new, h) = run.accepted_step(&mut f)?;
        run.serve_outputs(&mut f, t_new, h, times, &mut next, &mut out)?;
        run.advance(t_new);
    }
    Ok((out, run.stats))
}

/// Step-size factor after an accepted step with error norm `err < 1`, as
/// scipy: grow by at most `MAX_FACTOR`, and not at all right after a
/// rejection (the controller just learned the step was too large).
fn accepted_step_factor(err: f64, after_rejection: bool) -> f64 {
    let factor = if err == 0.0 {
        MAX_FACTOR
    } else {
        MAX_FACTOR.min(SAFETY * err.powf(ERROR_EXPONENT))
    };
    if after_rejection {
        factor.min(1.0)
    } else {
        factor
    }
}

/// Step-size factor after a rejected step. A non-finite trial is treated
/// as a maximal rejection (scipy's behaviour with a NaN error norm), so that
/// overflow caused by an overly large step is recovered from by shrinking
/// the step.
fn rejected_step_factor(err: f64, finite: bool) -> f64 {
    if finite {
        MIN_FACTOR.max(SAFETY * err.powf(ERROR_EXPONENT))
    } else {
        MIN_FACTOR
    }
}

/// State of an integration between accepted steps: time, state, stages,
/// step-size controller and statistics.
struct Run<'o> {
    opts: &'o Dop853Options,
    rtol: f64,
    atol: f64,
    t_end: f64,
    t: f64,
    /// Size of the next step attempt.
    h_abs: f64,
    /// Step attempts so far, accepted and rejected, against `max_steps`.
    attempts: u64,
    y: Vec<f64>,
    y_new: Vec<f64>,
    ytmp: Vec<f64>,
    k: Stages,
    dense: DenseStep,
    stats: Dop853Stats,
}

impl<'o> Run<'o> {
    /// Evaluates `f(t0, y0)` and chooses the first step size.
    fn start<F: FnMut(f64, &[f64], &mut [f64])>(
        f: &mut F,
        t0: f64,
        y0: &[f64],
        t_end: f64,
        opts: &'o Dop853Options,
    ) -> Result<Self, Dop853Error> {
        let n = y0.len();
        let mut stats = Dop853Stats::default();
        // Same clamp as scipy's `validate_tol`.
        let rtol = opts.rtol.max(100.0 * f64::EPSILON);
        let atol = opts.atol;

        let mut k: Stages = std::array::from_fn(|_| vec![0.0; n]);
        let y = y0.to_vec();
        f(t0, &y, &mut k[0]);
        stats.evaluations += 1;
        if !all_finite(&k[0]) {
            return Err(Dop853Error::NonFinite { t: t0 });
        }

        let mut h_abs = match opts.h_initial {
            Some(h) => h,
            None => {
                stats.evaluations += 1;
                select_initial_step(f, t0, &y, &k[0], t_end, opts.h_max, rtol, atol)
            }
        };
        if h_abs.is_nan() {
            // Cannot happen with finite f0, but never propagate a NaN time.
            h_abs = 0.0;
        }
        Ok(Self {
            opts,
            rtol,
            atol,
            t_end,
            t: t0,
            h_abs,
            attempts: 0,
            y,
            y_new: vec![0.0; n],
            ytmp: vec![0.0; n],
            k,
            dense: DenseStep::new(n),
            stats,
        })
    }

    /// Attempts steps from `t`, shrinking after each rejection, until one is
    /// accepted (scipy's `RungeKutta._step_impl`). Leaves the new state in
    /// `y_new`, its stages in `k`, and the size of the next attempt in
    /// `h_abs`; returns the step's end time and signed size.
    fn accepted_step<F: FnMut(f64, &[f64], &mut [f64])>(
        &mut self,
        f: &mut F,
    ) -> Result<(f64, f64), Dop853Error> {
        let t = self.t;
        // Steps below ten ulps of `t` would not advance time reliably.
        let min_step = 10.0 * (next_up(t) - t);
        if self.h_abs > self.opts.h_max {
            self.h_abs = self.opts.h_max;
        } else if self.h_abs < min_step {
            self.h_abs = min_step;
        }
        let mut step_rejected = false;
        let mut saw_non_finite = false;
        loop {
            if self.h_abs < min_step {
                return Err(if saw_non_finite {
                    Dop853Error::NonFinite { t }
                } else {
                    Dop853Error::StepTooSmall { t }
                });
            }
            if self.attempts >= self.opts.max_steps {
                return Err(Dop853Error::TooManySteps { t });
            }
            self.attempts += 1;
            // The last step lands exactly on `t_end`.
            let t_new = (t + self.h_abs).min(self.t_end);
            let h = t_new - t;
            self.h_abs = h.abs();

            let (err, finite) = self.trial_step(f, h);
            if finite && err < 1.0 {
                self.h_abs *= accepted_step_factor(err, step_rejected);
                self.stats.steps += 1;
                return Ok((t_new, h));
            }
            saw_non_finite |= !finite;
            self.h_abs *= rejected_step_factor(err, finite);
            step_rejected = true;
            self.stats.rejected += 1;
        }
    }

    /// One step of size `h` from `(t, y)` into `y_new`; returns its error
    /// norm and whether the error, the new state and its derivative are all
    /// finite.
    fn trial_step<F: FnMut(f64, &[f64], &mut [f64])>(&mut self, f: &mut F, h: f64) -> (f64, bool) {
        rk_step(
            f,
            self.t,
            &self.y,
            h,
            &mut self.k,
            &mut self.ytmp,
            &mut self.y_new,
        );
        self.stats.evaluations += N_STAGES as u64;
        let err = error_norm(&self.k, h, &self.y, &self.y_new, self.rtol, self.atol);
        let finite = err.is_finite() && all_finite(&self.y_new) && all_finite(&self.k[N_STAGES]);
        (err, finite)
    }

    /// Appends to `out` the states at the requested times inside the
    /// accepted step `(t, t_new]`, from `times[*next]` on. Times at the step
    /// end get `y_new` itself; the others the continuous extension, built
    /// only for steps that need it.
    fn serve_outputs<F: FnMut(f64, &[f64], &mut [f64])>(
        &mut self,
        f: &mut F,
        t_new: f64,
        h: f64,
        times: &[f64],
        next: &mut usize,
        out: &mut Vec<Vec<f64>>,
    ) -> Result<(), Dop853Error> {
        let mut dense_built = false;
        while *next < times.len() && times[*next] <= t_new {
            let ti = times[*next];
            if ti == t_new {
                out.push(self.y_new.clone());
            } else {
                if !dense_built {
                    self.dense.build(
                        f,
                        self.t,
                        h,
                        &self.y,
                        &self.y_new,
                        &mut self.k,
                        &mut self.ytmp,
                    );
                    self.stats.evaluations += (N_STAGES_EXTENDED - N_STAGES - 1) as u64;
                    dense_built = true;
                }
                let mut yi = vec![0.0; self.y.len()];
                self.dense.eval(ti, &self.y, &mut yi);
                if !all_finite(&yi) {
                    return Err(Dop853Error::NonFinite { t: ti });
                }
                out.push(yi);
            }
            *next += 1;
        }
        Ok(())
    }

    /// Moves to the end of the accepted step; its last stage is the next
    /// step's first (first same as last).
    fn advance(&mut self, t_new: f64) {
        self.t = t_new;
        std::mem::swap(&mut self.y, &mut self.y_new);
        self.k.swap(0, N_STAGES);
    }
}

/// Fixed-step integration with the main 8th-order formula (no error control),
/// used to measure the convergence order of the tableau.
#[cfg(test)]
fn fixed_steps<F: FnMut(f64, &[f64], &mut [f64])>(
    mut f: F,
    t0: f64,
    y0: &[f64],
    h: f64,
    n_steps: usize,
) -> Vec<f64> {
    let n = y0.len();
    let mut k: Stages = std::array::from_fn(|_| vec![0.0; n]);
    let mut y = y0.to_vec();
    let mut y_new = vec![0.0; n];
    let mut ytmp = vec![0.0; n];
    f(t0, &y, &mut k[0]);
    for i in 0..n_steps {
        let t = t0 + i as f64 * h;
        rk_step(&mut f, t, &y, h, &mut k, &mut ytmp, &mut y_new);
        std::mem::swap(&mut y, &mut y_new);
        k.swap(0, N_STAGES);
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Harmonic oscillator `q' = p, p' = -q`; from `(1, 0)`, `q = cos t`, `p = -sin t`.
    fn harmonic(_t: f64, y: &[f64], dy: &mut [f64]) {
        dy[0] = y[1];
        dy[1] = -y[0];
    }

    /// Van der Pol oscillator with `mu = 1`.
    fn van_der_pol(_t: f64, y: &[f64], dy: &mut [f64]) {
        dy[0] = y[1];
        dy[1] = (1.0 - y[0] * y[0]) * y[1] - y[0];
    }

    fn opts(rtol: f64, atol: f64) -> Dop853Options {
        Dop853Options {
            rtol,
            atol,
            ..Dop853Options::default()
        }
    }

    fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
        let mut v: Vec<f64> = (0..n)
            .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
            .collect();
        // Land exactly on the end point despite rounding.
        v[n - 1] = b;
        v
    }

    /// Max error of the harmonic oscillator solution against `(cos t, -sin t)`.
    fn harmonic_error(times: &[f64], ys: &[Vec<f64>]) -> f64 {
        times
            .iter()
            .zip(ys)
            .map(|(&t, y)| (y[0] - t.cos()).abs().max((y[1] + t.sin()).abs()))
            .fold(0.0, f64::max)
    }

    fn run_harmonic(times: &[f64], rtol: f64, atol: f64) -> (f64, Dop853Stats) {
        let (ys, stats) =
            dop853(harmonic, 0.0, &[1.0, 0.0], times, &opts(rtol, atol)).expect("harmonic run");
        assert_eq!(ys.len(), times.len());
        (harmonic_error(times, &ys), stats)
    }

    #[test]
    // scipy's decimal literals are kept verbatim to show the provenance.
    #[allow(clippy::excessive_precision)]
    fn coefficients_are_consistent() {
        // E3 is scipy's `B - b3` evaluated in f64, reproduced bit for bit.
        assert_eq!(E3[0], B[0] - 0.244094488188976377952755905512);
        assert_eq!(E3[8], B[8] - 0.733846688281611857341361741547);
        assert_eq!(E3[11], B[11] - 0.220588235294117647058823529412e-1);
        for s in [1, 2, 3, 4, 5, 6, 7, 9, 10] {
            assert_eq!(E3[s], B[s]);
        }
        // Row 12 of A is B (FSAL stage).
        assert_eq!(A[N_STAGES], &B[..]);
        // Row sums of A are the nodes C.
        for s in 1..N_STAGES_EXTENDED {
            let sum: f64 = A[s].iter().sum();
            assert!((sum - C[s]).abs() < 1e-13, "row {s}: {sum} vs {}", C[s]);
        }
        assert!((B.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        assert!(E5.iter().sum::<f64>().abs() < 1e-14);
        assert!(E3.iter().sum::<f64>().abs() < 1e-14);
    }

    #[test]
    fn harmonic_oscillator_1000_outputs() {
        let times = linspace(0.0, 100.0, 1000);
        let (err, stats) = run_harmonic(&times, 1e-12, 1e-12);
        println!("harmonic [0,100], 1000 outputs, rtol=atol=1e-12: max error {err:.3e}, {stats:?}");
        assert!(err <= 1e-9, "error {err}");
    }

    #[test]
    fn damped_oscillator_closed_form() {
        let alpha = 0.1_f64;
        let w = (1.0 - alpha * alpha / 4.0).sqrt();
        let (a, b) = (1.0, (1.0 + alpha / 2.0) / w);
        let exact = |t: f64| {
            let (s, c) = (w * t).sin_cos();
            let e = (-alpha * t / 2.0).exp();
            let q = e * (a * c + b * s);
            let p = e * ((-alpha / 2.0 * a + w * b) * c + (-alpha / 2.0 * b - w * a) * s);
            (q, p)
        };
        let f = |_t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1];
            dy[1] = -y[0] - alpha * y[1];
        };
        let times: Vec<f64> = (0..=20).map(f64::from).collect();
        let (ys, stats) =
            dop853(f, 0.0, &[1.0, 1.0], &times, &Dop853Options::default()).expect("damped run");
        let err = times
            .iter()
            .zip(&ys)
            .map(|(&t, y)| {
                let (q, p) = exact(t);
                (y[0] - q).abs().max((y[1] - p).abs())
            })
            .fold(0.0, f64::max);
        println!("damped oscillator t=0..20, default options: max error {err:.3e}, {stats:?}");
        assert!(err <= 1e-10, "error {err}");
    }

    #[test]
    fn dense_output_10000_times() {
        let times = linspace(0.0, 100.0, 10_000);
        let (err, stats) = run_harmonic(&times, 1e-12, 1e-12);
        println!("dense output, 10000 outputs: max error {err:.3e}, {stats:?}");
        assert!(err <= 1e-9, "error {err}");
        assert!(stats.evaluations < 20_000, "{stats:?}");
        // The dense outputs do not change the step sequence: same steps as a
        // run that only asks for the end point, plus 3 evaluations per step.
        let (_, plain) = run_harmonic(&[100.0], 1e-12, 1e-12);
        assert_eq!(stats.steps, plain.steps);
        assert_eq!(stats.rejected, plain.rejected);
        assert_eq!(stats.evaluations, plain.evaluations + 3 * plain.steps);
    }

    #[test]
    fn matches_scipy_step_statistics() {
        // Reference numbers from scipy 1.17.1:
        // solve_ivp(f, (0, T), y0, method="DOP853", rtol=r, atol=r), no t_eval.
        // Harmonic oscillator, T = 100, r = 1e-12: nfev 6002, 500 steps.
        let (_, st) = run_harmonic(&[100.0], 1e-12, 1e-12);
        assert_eq!((st.evaluations, st.steps, st.rejected), (6002, 500, 0));
        // Van der Pol, mu = 1, from (2, 0), T = 10.
        // r = 1e-10: nfev 1454, 93 accepted, y(10) = (-2.0083407825781734, 0.032907065813418)
        // r = 1e-13: nfev 2858, 207 accepted, y(10) = (-2.008340782579702, 0.032907065863273945)
        let cases = [
            (1e-10, 1454, 93, [-2.0083407825781734, 0.032907065813418]),
            (1e-13, 2858, 207, [-2.008340782579702, 0.032907065863273945]),
        ];
        for (r, nfev, steps, y_ref) in cases {
            let (ys, st) =
                dop853(van_der_pol, 0.0, &[2.0, 0.0], &[10.0], &opts(r, r)).expect("vdp run");
            println!("van der Pol rtol {r:e}: {st:?}, y(10) = {:?}", ys[0]);
            assert_eq!(st.evaluations, nfev);
            assert_eq!(st.steps, steps);
            assert_eq!(st.evaluations, 2 + 12 * (st.steps + st.rejected));
            for (a, b) in ys[0].iter().zip(y_ref) {
                assert!((a - b).abs() <= 1e-13, "{a} vs scipy {b}");
            }
        }
    }

    #[test]
    fn tolerance_convergence() {
        let times = linspace(0.0, 100.0, 1000);
        let (err_loose, _) = run_harmonic(&times, 1e-10, 1e-10);
        let (err_tight, _) = run_harmonic(&times, 1e-13, 1e-13);
        println!("harmonic: error at rtol 1e-10 {err_loose:.3e}, at rtol 1e-13 {err_tight:.3e}");
        assert!(err_loose > err_tight);
        assert!(err_tight <= 1e-11, "error {err_tight}");

        let times = linspace(0.0, 10.0, 101);
        let (loose, _) =
            dop853(van_der_pol, 0.0, &[2.0, 0.0], &times, &opts(1e-10, 1e-10)).expect("vdp");
        let (tight, _) =
            dop853(van_der_pol, 0.0, &[2.0, 0.0], &times, &opts(1e-13, 1e-13)).expect("vdp");
        let diff = loose
            .iter()
            .zip(&tight)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
            .fold(0.0, f64::max);
        println!("van der Pol: max |y(rtol 1e-10) - y(rtol 1e-13)| = {diff:.3e}");
        assert!(diff <= 1e-8, "difference {diff}");
    }

    #[test]
    fn blow_up_is_an_error() {
        let f = |_t: f64, y: &[f64], dy: &mut [f64]| dy[0] = y[0] * y[0];
        let res = dop853(f, 0.0, &[1.0], &[0.5, 2.0], &Dop853Options::default());
        println!("y' = y^2 blow-up: {res:?}");
        match res {
            Err(Dop853Error::StepTooSmall { t }) | Err(Dop853Error::NonFinite { t }) => {
                assert!((t - 1.0).abs() < 1e-3, "stopped at {t}");
            }
            other => panic!("expected a failure, got {other:?}"),
        }
    }

    #[test]
    fn nan_derivative_is_non_finite() {
        let f = |t: f64, _y: &[f64], dy: &mut [f64]| dy[0] = if t > 0.5 { f64::NAN } else { 1.0 };
        let res = dop853(f, 0.0, &[0.0], &[1.0], &Dop853Options::default());
        match res {
            Err(Dop853Error::NonFinite { t }) => assert!((t - 0.5).abs() < 1e-6, "t = {t}"),
            other => panic!("expected NonFinite, got {other:?}"),
        }
        let res = dop853(
            harmonic,
            0.0,
            &[f64::NAN, 0.0],
            &[1.0],
            &Dop853Options::default(),
        );
        assert!(matches!(res, Err(Dop853Error::NonFinite { .. })));
    }

    #[test]
    fn order_eight_with_fixed_steps() {
        // Global error at t = 10 of the fixed-step 8th-order formula. The step
        // sizes are chosen so that the errors (1e-9..1e-11) stay well above
        // round-off: at h = 0.1 the error is already ~1e-15 and the ratio is noise.
        let err = |h: f64| {
            let n = (10.0 / h).round() as usize;
            let y = fixed_steps(harmonic, 0.0, &[1.0, 0.0], h, n);
            let t = h * n as f64;
            (y[0] - t.cos()).abs().max((y[1] + t.sin()).abs())
        };
        let hs = [1.0, 0.5, 0.25];
        let errs = hs.map(err);
        for w in 0..2 {
            let order = (errs[w] / errs[w + 1]).log2();
            println!(
                "fixed step, t=10: err(h={}) {:.3e}, err(h={}) {:.3e}, ratio {:.1}, order {order:.3}",
                hs[w],
                errs[w],
                hs[w + 1],
                errs[w + 1],
                errs[w] / errs[w + 1]
            );
            assert!((7.6..=8.4).contains(&order), "order {order}");
        }
    }

    #[test]
    fn dense_interpolant_order_seven() {
        // On a single forced step from t = 0, the interpolant error at the
        // midpoint scales like h^8 (local error of a 7th-order interpolant).
        let mid_err = |h: f64| {
            let o = Dop853Options {
                h_initial: Some(h),
                h_max: h,
                rtol: 1.0,
                atol: 1.0,
                ..Dop853Options::default()
            };
            let (ys, st) = dop853(harmonic, 0.0, &[1.0, 0.0], &[h / 2.0, h], &o).expect("run");
            assert_eq!(st.steps, 1);
            (ys[0][0] - (h / 2.0).cos()).abs()
        };
        let (e1, e2) = (mid_err(0.8), mid_err(0.4));
        let order = (e1 / e2).log2();
        println!("interpolant midpoint error {e1:.3e} -> {e2:.3e}, local order {order:.2}");
        assert!(order > 7.0, "order {order}");
    }

    #[test]
    fn output_times_at_start_repeated_and_empty() {
        let times = [0.0, 0.0, 1.0, 1.0, 2.5, 2.5, 3.0];
        let (ys, _) = dop853(
            harmonic,
            0.0,
            &[1.0, 0.0],
            &times,
            &Dop853Options::default(),
        )
        .expect("run");
        assert_eq!(ys.len(), times.len());
        assert_eq!(ys[0], vec![1.0, 0.0]);
        assert_eq!(ys[1], vec![1.0, 0.0]);
        assert_eq!(ys[2], ys[3]);
        assert_eq!(ys[4], ys[5]);
        assert!(harmonic_error(&times, &ys) < 1e-11);

        let (ys, st) = dop853(
            harmonic,
            0.0,
            &[1.0, 0.0],
            &[0.0],
            &Dop853Options::default(),
        )
        .expect("run");
        assert_eq!(ys, vec![vec![1.0, 0.0]]);
        assert_eq!(st, Dop853Stats::default());
        let (ys, _) =
            dop853(harmonic, 0.0, &[1.0, 0.0], &[], &Dop853Options::default()).expect("run");
        assert!(ys.is_empty());
        // Scalar problem y' = y.
        let (ys, _) = dop853(
            |_t, y, dy| dy[0] = y[0],
            0.0,
            &[1.0],
            &[1.0],
            &Dop853Options::default(),
        )
        .expect("run");
        let err = (ys[0][0] - 1f64.exp()).abs();
        println!("y' = y to t = 1: error {err:.3e}");
        assert!(err < 1e-11, "error {err}");
    }

    #[test]
    fn limits_and_invalid_input() {
        let o = Dop853Options {
            h_max: 0.01,
            ..Dop853Options::default()
        };
        let (_, st) = dop853(harmonic, 0.0, &[1.0, 0.0], &[1.0], &o).expect("run");
        assert!(st.steps >= 100, "{st:?}");

        let o = Dop853Options {
            max_steps: 10,
            ..Dop853Options::default()
        };
        let res = dop853(harmonic, 0.0, &[1.0, 0.0], &[100.0], &o);
        assert!(matches!(res, Err(Dop853Error::TooManySteps { .. })));

        let d = Dop853Options::default();
        for times in [&[1.0, 0.5][..], &[-1.0], &[f64::NAN]] {
            let res = dop853(harmonic, 0.0, &[1.0, 0.0], times, &d);
            assert!(
                matches!(res, Err(Dop853Error::InvalidInput { .. })),
                "{times:?}"
            );
        }
        for (rtol, atol) in [(-1.0, 1e-14), (0.0, 0.0), (f64::NAN, 1e-14)] {
            let bad = Dop853Options { rtol, atol, ..d };
            let res = dop853(harmonic, 0.0, &[1.0, 0.0], &[1.0], &bad);
            assert!(matches!(res, Err(Dop853Error::InvalidInput { .. })));
        }
        let err = Dop853Error::StepTooSmall { t: 1.0 };
        assert!(err.to_string().contains("step size too small"));
    }
}
