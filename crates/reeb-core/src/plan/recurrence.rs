//! Which attractor an orbit ends on, from its samples on a section (or every
//! few steps): the smallest period k ≤ `max_period` at which its samples
//! recur within `tolerance`, and the first sample from which on they always
//! do. Online, one sample at a time, in memory of `max_period + 1` samples
//! and one counter per period, so that a backend can keep it per lane.
//!
//! Distances are the largest difference of one component (the max-norm), an
//! angle's (`wrap = Some(period)`) taken modulo its period.

use crate::models::Flows;

/// The detector's settings; see the module documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct Recurrence {
    pub max_period: usize,
    pub tolerance: f64,
    /// Per component: `Some(P)` for an angle of period P.
    pub wrap: Vec<Option<f64>>,
}

/// What an orbit's samples say at the end of its run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Its samples recur with period `period` (1: a fixed point of the
    /// section map) from sample `transient` on.
    Periodic { period: usize, transient: u64 },
    /// No period up to `max_period` holds: quasi-periodic or chaotic, or a
    /// transient longer than the run.
    Aperiodic,
}

/// One orbit's detector state.
#[derive(Debug, Clone)]
pub struct Samples {
    /// The last `max_period + 1` samples, sample n at `n mod (max_period + 1)`.
    ring: Vec<f64>,
    /// Samples seen.
    n: u64,
    /// Per period k (index k − 1): the first sample from which on every
    /// sample recurs within tolerance of the one k after it, as far as the
    /// samples go: where sample n does not return to sample n − k, n − k + 1.
    held_since: Vec<u64>,
}

impl Recurrence {
    /// A detector whose components have periods `wrap` (0: none).
    pub fn new(max_period: usize, tolerance: f64, wrap: &[f64]) -> Recurrence {
        Recurrence {
            max_period,
            tolerance,
            wrap: wrap.iter().map(|&w| (w > 0.0).then_some(w)).collect(),
        }
    }

    /// Components of one sample.
    pub fn dim(&self) -> usize {
        self.wrap.len()
    }

    /// A fresh detector for one orbit.
    pub fn start(&self) -> Samples {
        Samples {
            ring: vec![0.0; (self.max_period + 1) * self.dim()],
            n: 0,
            held_since: vec![0; self.max_period],
        }
    }

    /// The max-norm distance of two samples, angles modulo their period;
    /// NaN where a component is (a non-finite sample never recurs).
    pub fn distance(&self, a: &[f64], b: &[f64]) -> f64 {
        let mut d: f64 = 0.0;
        for ((x, y), wrap) in a.iter().zip(b).zip(&self.wrap) {
            let mut e = x - y;
            if let Some(p) = wrap {
                e -= p * (e / p).round();
            }
            if e.is_nan() {
                return f64::NAN;
            }
            d = d.max(e.abs());
        }
        d
    }

    /// Component `k` of sample `x`, an angle taken into [0, P).
    pub fn coordinate(&self, x: &[f64], k: usize) -> f64 {
        match self.wrap[k] {
            Some(p) => x[k].rem_euclid(p),
            None => x[k],
        }
    }

    /// Where sample `m` lies in the ring.
    fn slot(&self, m: u64) -> usize {
        (m % (self.max_period as u64 + 1)) as usize * self.dim()
    }

    /// Takes the orbit's next sample.
    pub fn push(&self, s: &mut Samples, x: &[f64]) {
        let (d, n) = (self.dim(), s.n);
        for k in 1..=self.max_period as u64 {
            if n < k {
                break;
            }
            let before = self.slot(n - k);
            let recurs = self.distance(x, &s.ring[before..before + d]) <= self.tolerance;
            if !recurs {
                s.held_since[k as usize - 1] = n + 1 - k;
            }
        }
        let at = self.slot(n);
        s.ring[at..at + d].copy_from_slice(x);
        s.n = n + 1;
    }

    /// The smallest period whose recurrence has held for at least two of
    /// its cycles (and four samples) up to the last sample, and since when.
    pub fn verdict(&self, s: &Samples) -> Verdict {
        for k in 1..=self.max_period as u64 {
            let since = s.held_since[k as usize - 1];
            if s.n >= since + k + confirmed(k) {
                return Verdict::Periodic {
                    period: k as usize,
                    transient: since,
                };
            }
        }
        Verdict::Aperiodic
    }

    /// The orbit's last `count` samples (at most `max_period + 1`), oldest
    /// first: a periodic orbit's points on the section, one per phase.
    pub fn last(&self, s: &Samples, count: usize) -> Vec<f64> {
        let d = self.dim();
        let count = count.min(s.n as usize).min(self.max_period + 1);
        let mut out = Vec::with_capacity(count * d);
        for m in s.n - count as u64..s.n {
            let at = self.slot(m);
            out.extend_from_slice(&s.ring[at..at + d]);
        }
        out
    }
}

/// One orbit's real slots, to read and write: a CPU block's lane, or a
/// plain vector.
pub trait OrbitSlots<R> {
    fn read(&self, k: usize) -> R;
    fn write(&mut self, k: usize, v: R);
}

impl<R: Copy> OrbitSlots<R> for Vec<R> {
    fn read(&self, k: usize) -> R {
        self[k]
    }
    fn write(&mut self, k: usize, v: R) {
        self[k] = v;
    }
}

/// Samples that must have recurred, after the first cycle, to confirm
/// period k: two cycles, and at least four.
fn confirmed(k: u64) -> u64 {
    (2 * k).max(4)
}

/// The detector of a plan as both backends keep it per orbit, in real
/// slots (`plan/slots.rs`) from `first` on: the samples taken, then per
/// period k its counter `held_since` (as [`Samples`]), then the last
/// `max_period` samples, newest first, each `dim` components. Instead of
/// [`Samples`]' ring the samples shift by one at each sample, so that a
/// GPU thread keeps them in named locals.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    pub first: usize,
    pub max_period: usize,
    pub dim: usize,
    pub tolerance: f64,
    /// Per component: its period (2π for an angle), or 0.
    pub wrap: Vec<f64>,
    /// The first step whose end (or, with a section, inside which a point)
    /// is sampled.
    pub skip_step: u64,
    /// Steps between samples; `None`: the section's points.
    pub every: Option<u64>,
}

impl Layout {
    /// Slots it takes.
    pub fn slot_count(&self) -> usize {
        1 + self.max_period * (1 + self.dim)
    }

    /// The slot of the count of samples.
    pub fn count(&self) -> usize {
        self.first
    }

    /// The slot of period k's counter (1 ≤ k ≤ `max_period`).
    pub fn held(&self, k: usize) -> usize {
        self.first + k
    }

    /// The slot of component `c` of the sample `j` before the next
    /// (1 ≤ j ≤ `max_period`: 1 the newest).
    pub fn sample(&self, j: usize, c: usize) -> usize {
        self.first + 1 + self.max_period + (j - 1) * self.dim + c
    }

    /// Its slots' names (each starts at 0).
    pub fn slot_names(&self) -> Vec<String> {
        let mut out = vec!["rec_n".to_string()];
        out.extend((1..=self.max_period).map(|k| format!("rec_held{k}")));
        for j in 1..=self.max_period {
            out.extend((0..self.dim).map(|c| format!("rec_x{j}_{c}")));
        }
        out
    }

    /// Is step `n1`'s end a sample (without a section)?
    pub fn due(&self, n1: u64) -> bool {
        self.every
            .is_some_and(|e| n1 >= self.skip_step && n1.is_multiple_of(e))
    }

    /// Takes sample `x` (a value per component) into an orbit's slots, as
    /// both backends do (the GPU's generated twin: `gpu/codegen.rs`
    /// `take_sample`): per period k its counter, from the distance to the
    /// sample k before (`recurrence_gap`, `recurrence_held`), then the
    /// samples shift by one.
    pub fn take<R: Flows>(&self, x: &[R], tolerance: R, wrap: &[R], s: &mut impl OrbitSlots<R>) {
        let n = s.read(self.count());
        for k in 1..=self.max_period {
            let mut gap = R::default();
            for (c, (&x, &w)) in x.iter().zip(wrap).enumerate() {
                gap = R::recurrence_gap(x, s.read(self.sample(k, c)), w, gap);
            }
            let mut held = s.read(self.held(k));
            R::recurrence_held(gap, tolerance, R::from_f64(k as f64), n, &mut held);
            s.write(self.held(k), held);
        }
        for j in (2..=self.max_period).rev() {
            for c in 0..self.dim {
                s.write(self.sample(j, c), s.read(self.sample(j - 1, c)));
            }
        }
        for (c, &x) in x.iter().enumerate() {
            s.write(self.sample(1, c), x);
        }
        s.write(self.count(), n + R::from_f64(1.0));
    }

    /// The detector of the host's labelling, with the same settings.
    pub fn detector(&self) -> Recurrence {
        Recurrence::new(self.max_period, self.tolerance, &self.wrap)
    }

    /// An orbit's verdict from its slots (`slot(k)`: slot k): `(period,
    /// transient)` as [`Recurrence::verdict`] gives them, period 0 for
    /// aperiodic (transient −1).
    pub fn verdict(&self, slot: impl Fn(usize) -> f64) -> (i32, i32) {
        let n = slot(self.count());
        for k in 1..=self.max_period {
            let since = slot(self.held(k));
            if n >= since + (k as u64 + confirmed(k as u64)) as f64 {
                return (k as i32, since as i32);
            }
        }
        (0, -1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn detector(max_period: usize, wrap: Vec<Option<f64>>) -> Recurrence {
        Recurrence {
            max_period,
            tolerance: 1e-6,
            wrap,
        }
    }

    fn verdict_of(
        r: &Recurrence,
        samples: impl IntoIterator<Item = Vec<f64>>,
    ) -> (Verdict, Samples) {
        let mut s = r.start();
        for x in samples {
            r.push(&mut s, &x);
        }
        (r.verdict(&s), s)
    }

    /// The slots' detector of both backends gives the ring detector's
    /// verdict, and keeps its last samples.
    #[test]
    fn the_backends_detector_in_slots_is_the_ring_detector() {
        let layout = Layout {
            first: 3,
            max_period: 5,
            dim: 2,
            tolerance: 1e-6,
            wrap: vec![0.0, std::f64::consts::TAU],
            skip_step: 0,
            every: Some(1),
        };
        let r = layout.detector();
        // The slots follow each other without a gap or an overlap.
        assert_eq!(layout.slot_names().len(), layout.slot_count());
        assert_eq!(layout.held(5) + 1, layout.sample(1, 0));
        assert_eq!(layout.sample(5, 1) + 1, layout.first + layout.slot_count());
        let cycle = [0.3, -0.8, 0.45];
        let orbits: Vec<Vec<Vec<f64>>> = vec![
            (0..40).map(|n| vec![0.5f64.powi(n), 7.0]).collect(),
            (0..40)
                .map(|n| vec![cycle[n % 3], n as f64 * std::f64::consts::PI])
                .collect(),
            (0..40)
                .map(|n| vec![(n as f64 * 0.618).fract(), 0.0])
                .collect(),
            (0..6).map(|_| vec![1.0, 1.0]).collect(),
        ];
        for xs in orbits {
            let mut slots = vec![0.0f64; layout.first + layout.slot_count()];
            let mut ring = r.start();
            for x in &xs {
                layout.take(x, layout.tolerance, &layout.wrap, &mut slots);
                r.push(&mut ring, x);
            }
            let want = match r.verdict(&ring) {
                Verdict::Periodic { period, transient } => (period as i32, transient as i32),
                Verdict::Aperiodic => (0, -1),
            };
            assert_eq!(layout.verdict(|k| slots[k]), want, "{xs:?}");
            let newest = r.last(&ring, 1);
            assert_eq!(
                &newest[..],
                &slots[layout.sample(1, 0)..layout.sample(1, 0) + 2]
            );
        }
    }

    #[test]
    fn a_converging_orbit_is_a_fixed_point_from_where_its_steps_are_below_tolerance() {
        let r = detector(8, vec![None, None]);
        // x_n = 0.5^n: the step 0.5^n from sample n − 1 to n is below 1e-6
        // from n = 20 on, so the samples recur from sample 19 on.
        let xs = (0..60).map(|n| vec![0.5f64.powi(n), 1.0]);
        let (v, _) = verdict_of(&r, xs);
        assert_eq!(
            v,
            Verdict::Periodic {
                period: 1,
                transient: 19
            }
        );
    }

    #[test]
    fn a_cycle_of_three_is_period_three_not_six() {
        let r = detector(8, vec![None]);
        let cycle = [0.1, 0.7, -0.4];
        let xs = (0..40).map(|n| vec![cycle[n % 3] + 1e-8 * (n as f64).sin()]);
        let (v, s) = verdict_of(&r, xs);
        assert_eq!(
            v,
            Verdict::Periodic {
                period: 3,
                transient: 0
            }
        );
        let points = r.last(&s, 3);
        let mut sorted = points.clone();
        sorted.sort_by(f64::total_cmp);
        assert!(
            (sorted[0] + 0.4).abs() < 1e-7 && (sorted[2] - 0.7).abs() < 1e-7,
            "{points:?}"
        );
    }

    #[test]
    fn an_irrational_rotation_is_aperiodic() {
        let r = detector(8, vec![Some(1.0)]);
        let golden = (5f64.sqrt() - 1.0) / 2.0;
        let xs = (0..200).map(|n| vec![(n as f64 * golden).fract()]);
        assert_eq!(verdict_of(&r, xs).0, Verdict::Aperiodic);
    }

    #[test]
    fn an_angle_recurs_modulo_its_period_only_when_told() {
        // Half a turn per sample: period 2 on the circle, unbounded on the line.
        let half_turns = || (0..30).map(|n| vec![n as f64 * std::f64::consts::PI]);
        let on_circle = detector(8, vec![Some(2.0 * std::f64::consts::PI)]);
        assert_eq!(
            verdict_of(&on_circle, half_turns()).0,
            Verdict::Periodic {
                period: 2,
                transient: 0
            }
        );
        let on_line = detector(8, vec![None]);
        assert_eq!(verdict_of(&on_line, half_turns()).0, Verdict::Aperiodic);
    }

    #[test]
    fn a_non_finite_sample_never_recurs_and_too_few_samples_decide_nothing() {
        let r = detector(4, vec![None]);
        let nan = (0..20).map(|n| vec![if n == 12 { f64::NAN } else { 1.0 }]);
        // Samples 12 and 13 do not return to 11 and 12: period 1 holds from
        // 13 on, 7 samples, confirmed.
        assert_eq!(
            verdict_of(&r, nan).0,
            Verdict::Periodic {
                period: 1,
                transient: 13
            }
        );
        let short = (0..3).map(|_| vec![1.0]);
        assert_eq!(verdict_of(&r, short).0, Verdict::Aperiodic);
    }
}
