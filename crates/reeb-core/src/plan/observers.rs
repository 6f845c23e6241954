//! Observer configuration: what a run records besides its final state, and
//! the checks on it that do not depend on the model. The per-step logic is
//! shared functions in `models/events.rs`.

use super::stop::StopObs;

/// Direction of an event crossing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// From below to above the value.
    #[default]
    Up,
    Down,
    Both,
}

/// A Poincaré section.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum Section {
    /// Sample at `t0 + phase + k·period`, k = 0, 1, …: exact when the period
    /// (and phase) are whole multiples of the step, else interpolated.
    Stroboscopic { period: f64, phase: f64 },
    /// Stroboscopic at each trajectory's forcing period 2π/ω (the model's
    /// forcing frequency, which may run along an axis), after `skip` periods.
    Forced { skip: f64 },
    /// Sample where `var` crosses `value` in `direction`, located inside the step.
    Crossing {
        var: String,
        value: f64,
        direction: Direction,
    },
}

/// A variable an observer records: a state variable, `t`, or a vector
/// (`q` of Kepler is `[q1, q2]`: its arrays carry a trailing component
/// axis), as the scene names it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OutVar {
    pub name: String,
    pub components: Vec<String>,
}

impl From<&str> for OutVar {
    /// A variable of one component, itself.
    fn from(name: &str) -> OutVar {
        OutVar {
            name: name.into(),
            components: vec![name.into()],
        }
    }
}

/// The components of `vars`, in order.
pub fn components(vars: &[OutVar]) -> impl Iterator<Item = &String> {
    vars.iter().flat_map(|v| &v.components)
}

/// Poincaré-section observer.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PoincareObs {
    pub section: Section,
    /// Variables recorded at each point (state names or `t`).
    pub vars: Vec<OutVar>,
    /// Points kept per trajectory (later ones are counted but dropped).
    pub max_points: usize,
}

/// Trajectory observer: the state every `every` steps, from step 0.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TrajectoryObs {
    pub every: u64,
    pub vars: Vec<OutVar>,
}

/// Limit-cycle statistics over the last part of the run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CycleObs {
    /// The variable whose oscillation is measured.
    pub var: String,
    /// Crossing level for the period (upward crossings).
    pub level: f64,
    /// Fraction of the steps skipped before measuring (transient).
    pub skip: f64,
}

impl Default for CycleObs {
    fn default() -> Self {
        CycleObs {
            var: "q".into(),
            level: 0.0,
            skip: 0.5,
        }
    }
}

/// Time averages: the plain mean of each variable's values at the ends of
/// the steps after the first `skip` fraction of the run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AverageObs {
    /// State variables.
    pub vars: Vec<OutVar>,
    pub skip: f64,
}

/// Resonance capture: the ratio p:q whose value p/q the mean of `var` is
/// within `tolerance` of (the first such, in the order given).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ResonanceObs {
    pub var: String,
    pub ratios: Vec<[i64; 2]>,
    pub tolerance: f64,
}

impl ResonanceObs {
    /// The index into `ratios` of the resonance `mean` is captured in, or −1.
    pub fn classify(&self, mean: f64) -> i32 {
        self.ratios
            .iter()
            .position(|[p, q]| (mean - *p as f64 / *q as f64).abs() <= self.tolerance)
            .map_or(-1, |k| k as i32)
    }

    /// `p:q` of ratio `k`, and `none` for `k` = the number of ratios.
    pub fn label(&self, k: usize) -> String {
        match self.ratios.get(k) {
            Some([p, q]) => format!("{p}:{q}"),
            None => "none".into(),
        }
    }

    /// How many of the trajectories with resonance `index` (from
    /// [`Self::classify`]) each ratio captured, then how many none did.
    pub fn counts(&self, index: &[i32]) -> Vec<u64> {
        let none = self.ratios.len();
        let mut counts = vec![0u64; none + 1];
        for k in index {
            counts[usize::try_from(*k).unwrap_or(none)] += 1;
        }
        counts
    }
}

/// Finite-time Lyapunov exponents by Benettin's method: `vectors`
/// deviation vectors, re-orthonormalised every `every` steps, the logarithms
/// of the growth summed after the first `skip` fraction of the run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LyapunovObs {
    pub vectors: usize,
    pub every: u64,
    pub skip: f64,
}

impl LyapunovObs {
    /// The step of the sample the sums start from, in a run of `steps`:
    /// the first sample at or after the skipped fraction.
    pub fn skip_step(&self, steps: u64) -> u64 {
        let skip = (self.skip * steps as f64).ceil() as u64;
        skip.div_ceil(self.every) * self.every
    }
}

impl Default for LyapunovObs {
    fn default() -> Self {
        LyapunovObs {
            vectors: 1,
            every: 1,
            skip: 0.0,
        }
    }
}

/// The Fast Lyapunov Indicator or MEGNO: one deviation vector, its norm
/// sampled every `every` steps.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SampledObs {
    pub every: u64,
}

impl Default for SampledObs {
    fn default() -> Self {
        SampledObs { every: 1 }
    }
}

/// The generalized alignment index GALI_k (Skokos, Bountis and
/// Antonopoulos 2007): the volume of the parallelepiped of `k` unit
/// deviation vectors, sampled every `every` steps.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GaliObs {
    pub k: usize,
    pub every: u64,
}

impl Default for GaliObs {
    fn default() -> Self {
        GaliObs { k: 3, every: 1 }
    }
}

/// Which attractor each orbit ends on (`plan/recurrence.rs`): its samples
/// (the section's points where the run has a section, else the state every
/// `every` steps) after the first `skip` fraction of the run, tested for a
/// period k ≤ `max_period` at which they recur within `tolerance`
/// (max-norm; the `angles` modulo 2π).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AttractorObs {
    pub max_period: usize,
    pub tolerance: f64,
    pub skip: f64,
    /// Steps between samples without a section; `None`: [`Self::every`]'s default.
    pub every: Option<u64>,
    /// The sampled variables: the section's state variables, or the state.
    pub vars: Vec<OutVar>,
    /// Components taken modulo 2π.
    pub angles: Vec<String>,
}

impl AttractorObs {
    /// The most periods one orbit's detector keeps (its state per orbit
    /// grows with it: `max_period` samples and counters).
    pub const MAX_PERIOD: usize = 64;

    /// The steps between samples without a section: as given, or 64 (fewer
    /// in runs of fewer than 4096 steps, so that at least 64 samples are
    /// taken). A multiple of 64 costs the CPU's runs of steps nothing: they
    /// end at multiples of 64 anyway.
    pub fn every(&self, steps: u64) -> u64 {
        self.every.unwrap_or_else(|| (steps / 64).clamp(1, 64))
    }

    /// The first step whose end is sampled: the skipped fraction rounded up.
    pub fn skip_step(&self, steps: u64) -> u64 {
        (self.skip * steps as f64).ceil() as u64
    }

    /// Per sampled component: its period (2π for one of the `angles`), or 0.
    pub fn wrap(&self) -> Vec<f64> {
        components(&self.vars)
            .map(|c| match self.angles.contains(c) {
                true => std::f64::consts::TAU,
                false => 0.0,
            })
            .collect()
    }

    /// The first step whose end is a sample without a section: the first
    /// multiple of `every` from [`Self::skip_step`] on.
    pub fn first_sample(&self, steps: u64) -> u64 {
        let every = self.every(steps);
        self.skip_step(steps).div_ceil(every) * every
    }

    /// Samples taken every `every` steps from [`Self::first_sample`] on.
    pub fn samples(&self, steps: u64) -> u64 {
        match self.first_sample(steps) {
            s if s > steps => 0,
            s => (steps - s) / self.every(steps) + 1,
        }
    }
}

impl Default for AttractorObs {
    fn default() -> Self {
        AttractorObs {
            max_period: 8,
            tolerance: 1e-3,
            skip: 0.5,
            every: None,
            vars: vec![],
            angles: vec![],
        }
    }
}

/// Everything a run records.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Observers {
    /// Variables whose final value is recorded (state names or `t`).
    pub final_vars: Vec<OutVar>,
    pub trajectory: Option<TrajectoryObs>,
    pub poincare: Option<PoincareObs>,
    pub cycle: Option<CycleObs>,
    pub average: Option<AverageObs>,
    /// Classifies the mean of one of the averaged variables.
    pub resonance: Option<ResonanceObs>,
    /// Stops a trajectory after the first step at which it holds.
    pub stop: Option<StopObs>,
    pub lyapunov: Option<LyapunovObs>,
    pub fli: Option<SampledObs>,
    pub megno: Option<SampledObs>,
    /// The smaller alignment index of two deviation vectors (Skokos 2001).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sali: Option<SampledObs>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gali: Option<GaliObs>,
    /// Which attractor each orbit ends on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub attractors: Option<AttractorObs>,
}

impl Observers {
    /// Every variable name an observer refers to.
    pub fn variables(&self) -> Vec<String> {
        let mut v: Vec<String> = components(&self.final_vars).cloned().collect();
        if let Some(t) = &self.trajectory {
            v.extend(components(&t.vars).cloned());
        }
        if let Some(p) = &self.poincare {
            v.extend(components(&p.vars).cloned());
            if let Section::Crossing { var, .. } = &p.section {
                v.push(var.clone());
            }
        }
        if let Some(c) = &self.cycle {
            v.push(c.var.clone());
        }
        if let Some(a) = &self.average {
            v.extend(components(&a.vars).cloned());
        }
        if let Some(s) = &self.stop {
            v.extend(s.reads.iter().filter(|r| s.state(r)).cloned());
        }
        if let Some(a) = &self.attractors {
            v.extend(components(&a.vars).cloned());
        }
        v
    }

    /// Checks values that do not depend on the model; errors name the field.
    pub fn validate(&self, steps: u64) -> Result<(), (String, String)> {
        let e = |f: &str, m: String| Err((f.to_string(), m));
        if let Some(t) = &self.trajectory {
            if t.every == 0 {
                return e("output.trajectory.every", "must be at least 1".into());
            }
            if t.every > steps {
                return e(
                    "output.trajectory.every",
                    format!("{} is more than the {steps} steps of the run", t.every),
                );
            }
            if t.vars.is_empty() {
                return e("output.trajectory.vars", "names no variable".into());
            }
        }
        if let Some(p) = &self.poincare {
            if p.max_points == 0 {
                return e("output.poincare.max_points", "must be at least 1".into());
            }
            if p.vars.is_empty() {
                return e("output.poincare.vars", "names no variable".into());
            }
            match &p.section {
                Section::Stroboscopic { period, phase } => check_strobe(*period, *phase)?,
                Section::Forced { skip } => {
                    check_skip(*skip).map_err(|m| ("output.poincare.skip".to_string(), m))?
                }
                Section::Crossing { value, .. } => {
                    if !value.is_finite() {
                        return e("output.poincare.value", "is not a finite number".into());
                    }
                }
            }
        }
        if let Some(c) = &self.cycle {
            if !(0.0..1.0).contains(&c.skip) {
                return e(
                    "output.cycle.skip",
                    "must be in [0, 1): the fraction of the run skipped as transient".into(),
                );
            }
            if !c.level.is_finite() {
                return e("output.cycle.level", "is not a finite number".into());
            }
        }
        if let Some(a) = &self.average {
            if !(0.0..1.0).contains(&a.skip) {
                return e(
                    "output.average.skip",
                    "must be in [0, 1): the fraction of the run skipped before averaging".into(),
                );
            }
        }
        if let Some(r) = &self.resonance {
            validate_resonance(r)?;
        }
        if let Some(a) = &self.attractors {
            validate_attractors(a, steps, self.poincare.is_some())?;
        }
        self.validate_indicators(steps)
    }

    /// The chaos indicators' values that do not depend on the model (the
    /// vectors' bound, the tangent dimension, is the plan's check).
    fn validate_indicators(&self, steps: u64) -> Result<(), (String, String)> {
        let every = |name: &str, every: u64| {
            let field = format!("output.{name}.every");
            match every {
                0 => Err((field, "must be at least 1".into())),
                e if e > steps => Err((
                    field,
                    format!("{e} is more than the {steps} steps of the run"),
                )),
                _ => Ok(()),
            }
        };
        if let Some(l) = &self.lyapunov {
            every("lyapunov", l.every)?;
            if l.vectors == 0 {
                return Err((
                    "output.lyapunov.vectors".into(),
                    "must be at least 1".into(),
                ));
            }
            if !(0.0..1.0).contains(&l.skip) {
                return Err((
                    "output.lyapunov.skip".into(),
                    "must be in [0, 1): the fraction of the run skipped before summing".into(),
                ));
            }
            let start = l.skip_step(steps);
            if start + l.every > steps {
                return Err((
                    "output.lyapunov.skip".into(),
                    format!(
                        "{} of the {steps} steps leaves no sample to sum: the sums start at the sample of step {start} and the next is at step {}, after the run; lower skip or every",
                        l.skip,
                        start + l.every
                    ),
                ));
            }
        }
        for (name, obs) in [("fli", &self.fli), ("megno", &self.megno)] {
            if let Some(o) = obs {
                every(name, o.every)?;
            }
        }
        self.validate_alignment(every)?;
        if let (Some(f), Some(m)) = (&self.fli, &self.megno) {
            let shared = "FLI and MEGNO share one deviation vector";
            one_rate(("fli", f.every), ("megno", m.every), shared)?;
        }
        Ok(())
    }

    /// SALI's and GALI's values that do not depend on the model (`every`:
    /// the check of a sampling period).
    fn validate_alignment(
        &self,
        every: impl Fn(&str, u64) -> Result<(), (String, String)>,
    ) -> Result<(), (String, String)> {
        if let Some(s) = &self.sali {
            every("sali", s.every)?;
        }
        if let Some(g) = &self.gali {
            every("gali", g.every)?;
            if g.k < 2 {
                return Err((
                    "output.gali.k".into(),
                    format!(
                        "{} is below 2: GALI_k measures the volume of k ≥ 2 unit deviation vectors",
                        g.k
                    ),
                ));
            }
        }
        if let (Some(s), Some(g)) = (&self.sali, &self.gali) {
            let shared = "SALI and GALI share their deviation vectors";
            one_rate(("sali", s.every), ("gali", g.every), shared)?;
        }
        Ok(())
    }

    /// How many deviation vectors SALI and GALI share (SALI two, GALI_k
    /// k), and their sampling period; `None` if neither is asked for.
    pub fn alignment(&self) -> Option<(usize, u64)> {
        let sali = self.sali.as_ref().map(|s| (2, s.every));
        let gali = self.gali.as_ref().map(|g| (g.k, g.every));
        match (sali, gali) {
            (Some((m, e)), Some((k, _))) => Some((m.max(k), e)),
            (a, b) => a.or(b),
        }
    }

    /// Whether any chaos indicator is asked for.
    pub fn has_indicators(&self) -> bool {
        self.lyapunov.is_some() || self.chaos_every().is_some() || self.alignment().is_some()
    }

    /// The FLI/MEGNO vector's sampling period, if either is asked for.
    pub fn chaos_every(&self) -> Option<u64> {
        self.fli.as_ref().or(self.megno.as_ref()).map(|o| o.every)
    }
}

/// Two indicators whose deviation vectors are `shared` sample at one rate:
/// the second's `every` is refused where it differs from the first's.
fn one_rate(
    (first, a): (&str, u64),
    (second, b): (&str, u64),
    shared: &str,
) -> Result<(), (String, String)> {
    match a == b {
        true => Ok(()),
        false => Err((
            format!("output.{second}.every"),
            format!("{b} differs from output.{first}.every = {a}: {shared}, sampled at one rate"),
        )),
    }
}

/// The attractor detector's settings (`sectioned`: the run samples its
/// section, not every `every` steps).
fn validate_attractors(
    a: &AttractorObs,
    steps: u64,
    sectioned: bool,
) -> Result<(), (String, String)> {
    let e = |f: &str, m: String| Err((format!("output.attractors.{f}"), m));
    if a.max_period < 1 {
        return e(
            "max_period",
            "must be at least 1 (1: fixed points only)".into(),
        );
    }
    if a.max_period > AttractorObs::MAX_PERIOD {
        return e(
            "max_period",
            format!(
                "{} is more than {}: each orbit keeps its last max_period samples",
                a.max_period,
                AttractorObs::MAX_PERIOD
            ),
        );
    }
    if !(a.tolerance.is_finite() && a.tolerance > 0.0) {
        return e("tolerance", "must be a finite number above 0".into());
    }
    if !(0.0..1.0).contains(&a.skip) {
        return e(
            "skip",
            "must be in [0, 1): the fraction of the run skipped before sampling".into(),
        );
    }
    match a.every {
        Some(0) => return e("every", "must be at least 1".into()),
        Some(k) if k > steps => {
            return e(
                "every",
                format!("{k} is more than the {steps} steps of the run"),
            )
        }
        _ => {}
    }
    let samples = a.samples(steps);
    if !sectioned && samples < 4 {
        return e(
            "every",
            format!(
                "{} steps between samples leave {samples} samples after the skipped {} of the {steps} steps; a period is confirmed by at least 4: lower every or skip",
                a.every(steps),
                a.skip
            ),
        );
    }
    Ok(())
}

/// A resonance's ratios and tolerance.
fn validate_resonance(r: &ResonanceObs) -> Result<(), (String, String)> {
    let e = |f: &str, m: String| Err((f.to_string(), m));
    if r.ratios.is_empty() {
        return e("output.resonance.ratios", "names no ratio".into());
    }
    if let Some([p, q]) = r.ratios.iter().find(|[p, q]| *p <= 0 || *q <= 0) {
        return e(
            "output.resonance.ratios",
            format!("{p}:{q} has a term ≤ 0: each ratio is [p, q] with p, q ≥ 1"),
        );
    }
    if !(r.tolerance.is_finite() && r.tolerance > 0.0) {
        return e(
            "output.resonance.tolerance",
            format!("{} must be a number > 0", r.tolerance),
        );
    }
    for (j, [p, q]) in r.ratios.iter().enumerate() {
        let same =
            |[a, b]: &[i64; 2]| i128::from(*a) * i128::from(*q) == i128::from(*p) * i128::from(*b);
        if let Some([a, b]) = r.ratios[..j].iter().find(|x| same(x)) {
            return e(
                "output.resonance.ratios",
                format!("{p}:{q} is the same ratio as {a}:{b}, given before it, so it could never be chosen: give each ratio once, in lowest terms"),
            );
        }
    }
    Ok(())
}

impl ResonanceObs {
    /// The pairs of ratios whose windows `p/q ± tolerance` overlap (the
    /// earlier one of a pair takes the means in both), in the order given.
    pub fn overlaps(&self) -> Vec<(usize, usize)> {
        let value = |[p, q]: [i64; 2]| p as f64 / q as f64;
        let mut out = vec![];
        for j in 0..self.ratios.len() {
            for k in 0..j {
                let gap = (value(self.ratios[j]) - value(self.ratios[k])).abs();
                if gap <= 2.0 * self.tolerance {
                    out.push((k, j));
                }
            }
        }
        out
    }
}

/// Is the stroboscopic section of `plan` sampled exactly (period and phase
/// whole multiples of every trajectory's step)? Then no interpolation is needed.
pub fn strobe_steps(period: f64, phase: f64, dt: f64) -> Option<(u64, u64)> {
    let whole = |x: f64| {
        let r = (x / dt).round();
        (r >= 0.0 && ((x / dt) - r).abs() <= 1e-9 * r.max(1.0)).then_some(r as u64)
    };
    match (whole(period), whole(phase)) {
        (Some(n), Some(k)) if n > 0 => Some((n, k)),
        _ => None,
    }
}

/// A stroboscopic section's period and phase (phase after any skipped periods).
pub fn check_strobe(period: f64, phase: f64) -> Result<(), (String, String)> {
    if period.is_finite() && period > 0.0 && phase.is_finite() && phase >= 0.0 {
        Ok(())
    } else {
        Err((
            "output.poincare.period".into(),
            "needs period > 0 and phase ≥ 0".into(),
        ))
    }
}

/// Periods skipped before a section starts.
pub fn check_skip(skip: f64) -> Result<(), String> {
    if skip.is_finite() && skip >= 0.0 && skip.fract() == 0.0 {
        Ok(())
    } else {
        Err("must be a whole number of periods ≥ 0".into())
    }
}

impl Observers {
    /// Is the section stroboscopic (fixed or forcing period)?
    pub fn stroboscopic(&self) -> bool {
        matches!(
            self.poincare.as_ref().map(|p| &p.section),
            Some(Section::Stroboscopic { .. } | Section::Forced { .. })
        )
    }
}
