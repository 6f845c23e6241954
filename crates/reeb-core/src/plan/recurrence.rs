//! Which attractor an orbit ends on, from its samples on a section (or every
//! few steps): the smallest period k ≤ `max_period` at which its samples
//! recur within `tolerance`, and the first sample from which on they always
//! do. Online, one sample at a time, in memory of `max_period + 1` samples
//! and one counter per period, so that a backend can keep it per lane.
//!
//! Distances are the largest difference of one component (the max-norm), an
//! angle's (`wrap = Some(period)`) taken modulo its period.

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
    /// Per period k (index k − 1): one past the last sample that did not
    /// recur within tolerance of the sample k before it (0: none failed
    /// after the first k, which cannot be compared).
    held_since: Vec<u64>,
}

impl Recurrence {
    /// Components of one sample.
    pub fn dim(&self) -> usize {
        self.wrap.len()
    }

    /// A fresh detector for one orbit.
    pub fn start(&self) -> Samples {
        Samples {
            ring: vec![0.0; (self.max_period + 1) * self.dim()],
            n: 0,
            held_since: (1..=self.max_period as u64).collect(),
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
                s.held_since[k as usize - 1] = n + 1;
            }
        }
        let at = self.slot(n);
        s.ring[at..at + d].copy_from_slice(x);
        s.n = n + 1;
    }

    /// The smallest period that has held for at least two of its cycles
    /// (and four samples) up to the last sample, and since when.
    pub fn verdict(&self, s: &Samples) -> Verdict {
        for k in 1..=self.max_period as u64 {
            let since = s.held_since[k as usize - 1];
            let confirmed = (2 * k).max(4);
            if s.n >= since + confirmed {
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

    #[test]
    fn a_converging_orbit_is_a_fixed_point_from_where_its_steps_are_below_tolerance() {
        let r = detector(8, vec![None, None]);
        // x_n = 0.5^n: the step 0.5^n is below 1e-6 from n = 20 on.
        let xs = (0..60).map(|n| vec![0.5f64.powi(n), 1.0]);
        let (v, _) = verdict_of(&r, xs);
        assert_eq!(
            v,
            Verdict::Periodic {
                period: 1,
                transient: 20
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
                transient: 3
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
                transient: 2
            }
        );
        let on_line = detector(8, vec![None]);
        assert_eq!(verdict_of(&on_line, half_turns()).0, Verdict::Aperiodic);
    }

    #[test]
    fn a_non_finite_sample_never_recurs_and_too_few_samples_decide_nothing() {
        let r = detector(4, vec![None]);
        let nan = (0..20).map(|n| vec![if n == 12 { f64::NAN } else { 1.0 }]);
        // After the NaN at 12, period 1 holds from 14 on: 6 samples, confirmed.
        assert_eq!(
            verdict_of(&r, nan).0,
            Verdict::Periodic {
                period: 1,
                transient: 14
            }
        );
        let short = (0..3).map(|_| vec![1.0]);
        assert_eq!(verdict_of(&r, short).0, Verdict::Aperiodic);
    }
}
