//! Exact solutions (SPEC §2, §4) that tests, `reeb verify` and reports compare with.

/// Damped, forced oscillator `q'' + α q' + q = β sin ωt` from (q0, p0) at
/// t = 0: returns (q, p = q') at t. Solved in closed form: the particular
/// solution `C sin ωt + D cos ωt` plus the homogeneous one for α < 2
/// (underdamped), α = 2 (critical) or α > 2 (overdamped).
pub fn damped_oscillator(
    alpha: f64,
    beta: f64,
    omega: f64,
    q0: f64,
    p0: f64,
    t: f64,
) -> (f64, f64) {
    // Particular solution: (1 − ω²) C − α ω D = β, α ω C + (1 − ω²) D = 0.
    let (c, d) = if beta == 0.0 {
        (0.0, 0.0)
    } else {
        let a = 1.0 - omega * omega;
        let b = alpha * omega;
        let det = a * a + b * b;
        (beta * a / det, -beta * b / det)
    };
    let (sw, cw) = (omega * t).sin_cos();
    let qp = c * sw + d * cw;
    let pp = omega * (c * cw - d * sw);
    // Homogeneous part from the initial values minus the particular ones at 0.
    let y0 = q0 - d;
    let v0 = p0 - omega * c;
    let (qh, ph) = if (alpha - 2.0).abs() < 1e-9 {
        let lam = -alpha / 2.0;
        let b = v0 - lam * y0;
        let e = (lam * t).exp();
        ((y0 + b * t) * e, (lam * (y0 + b * t) + b) * e)
    } else if alpha < 2.0 {
        let w = (1.0 - alpha * alpha / 4.0).sqrt();
        let lam = -alpha / 2.0;
        let b = (v0 - lam * y0) / w;
        let e = (lam * t).exp();
        let (s, co) = (w * t).sin_cos();
        let q = e * (y0 * co + b * s);
        let p = lam * q + e * w * (-y0 * s + b * co);
        (q, p)
    } else {
        let disc = (alpha * alpha - 4.0).sqrt();
        let r1 = (-alpha + disc) / 2.0;
        let r2 = (-alpha - disc) / 2.0;
        let b = (v0 - r1 * y0) / (r2 - r1);
        let a = y0 - b;
        let (e1, e2) = ((r1 * t).exp(), (r2 * t).exp());
        (a * e1 + b * e2, a * r1 * e1 + b * r2 * e2)
    };
    (qh + qp, ph + pp)
}

/// The action s of the unforced damped oscillator from its contact invariant
/// `H(t) = H(0) e^{−αt}`, `H = p²/2 + q²/2 + α s` (α ≠ 0).
pub fn damped_oscillator_action(alpha: f64, q0: f64, p0: f64, s0: f64, t: f64) -> f64 {
    let h0 = 0.5 * (p0 * p0 + q0 * q0) + alpha * s0;
    let (q, p) = damped_oscillator(alpha, 0.0, 0.0, q0, p0, t);
    (h0 * (-alpha * t).exp() - 0.5 * (p * p + q * q)) / alpha
}

/// Harmonic oscillator (van der Pol with ε = 0): (q, s = q') at t.
pub fn harmonic(q0: f64, s0: f64, t: f64) -> (f64, f64) {
    let (sn, cs) = t.sin_cos();
    (q0 * cs + s0 * sn, -q0 * sn + s0 * cs)
}

/// Angular frequency of the S2(CBABC) orbit of the harmonic oscillator
/// (SPEC §4.1), from the eigenvalues of the one-step map: cos(ωτ) = 1 − τ²/2.
pub fn harmonic_s2_frequency(tau: f64) -> f64 {
    (1.0 - tau * tau / 2.0).acos() / tau
}

/// SPEC §4.1 series of the same frequency to τ⁸.
pub fn harmonic_s2_frequency_series(tau: f64) -> f64 {
    let t2 = tau * tau;
    1.0 + t2 / 24.0
        + 3.0 * t2 * t2 / 640.0
        + 5.0 * t2.powi(3) / 7168.0
        + 35.0 * t2.powi(4) / 294912.0
}

/// SPEC §4.4: Poincaré–Lindstedt frequency of the van der Pol limit cycle
/// under S2(CBABC), `ω = Σ ω_ij ε^i τ^{2j}`, truncated at ε⁴ and τ⁶.
pub fn van_der_pol_s2_frequency(eps: f64, tau: f64) -> f64 {
    const W: [[f64; 4]; 3] = [
        [1.0, 1.0 / 24.0, 3.0 / 640.0, 5.0 / 7168.0],
        [-1.0 / 16.0, 27.0 / 128.0, 149.0 / 2048.0, 559.0 / 16384.0],
        [
            17.0 / 3072.0,
            781.0 / 73728.0,
            -339041.0 / 3538944.0,
            4695149.0 / 84934656.0,
        ],
    ];
    let t2 = tau * tau;
    (0..3)
        .map(|i| eps.powi(2 * i as i32) * (0..4).map(|j| W[i][j] * t2.powi(j as i32)).sum::<f64>())
        .sum()
}

/// SPEC §4.3: determinant and eigenvalues of the Jacobian of S2(CBABC) for
/// van der Pol at the fixed point (0, 0): `det = e^{ετ}`, eigenvalues
/// `(α ± sqrt β)/4` with `α = (2 − τ²)(e^{ετ} + 1)`, `β = α² − 16 e^{ετ}`.
/// Returns (det, trace, modulus of the larger eigenvalue).
pub fn van_der_pol_fixed_point(eps: f64, tau: f64) -> (f64, f64, f64) {
    let e = (eps * tau).exp();
    let a = (2.0 - tau * tau) * (e + 1.0);
    let b = a * a - 16.0 * e;
    let modulus = if b >= 0.0 {
        (a.abs() + b.sqrt()) / 4.0
    } else {
        e.sqrt()
    };
    (e, a / 2.0, modulus)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn damped_oscillator_solves_its_ode() {
        for (alpha, beta, omega) in [
            (0.1, 0.0, 0.0),
            (2.0, 0.0, 0.0),
            (3.5, 0.0, 0.0),
            (0.3, 0.7, 1.3),
            (2.0, 0.5, 0.8),
        ] {
            let h = 1e-4;
            for t in [0.3, 1.7, 5.0] {
                let (q, p) = damped_oscillator(alpha, beta, omega, 1.0, 1.0, t);
                let (qa, pa) = damped_oscillator(alpha, beta, omega, 1.0, 1.0, t + h);
                let (qb, pb) = damped_oscillator(alpha, beta, omega, 1.0, 1.0, t - h);
                assert!(((qa - qb) / (2.0 * h) - p).abs() < 1e-7);
                let acc = (pa - pb) / (2.0 * h);
                assert!(
                    (acc - (-q - alpha * p + beta * (omega * t).sin())).abs() < 1e-6,
                    "{alpha} {beta} {t}"
                );
            }
            let (q, p) = damped_oscillator(alpha, beta, omega, 1.0, 1.0, 0.0);
            assert!((q - 1.0).abs() < 1e-14 && (p - 1.0).abs() < 1e-14);
        }
        // SPEC's closed form for (q0, p0) = (1, 1), d = sqrt(α² − 4) real (α > 2).
        let alpha: f64 = 3.0;
        let d = (alpha * alpha - 4.0).sqrt();
        let t = 1.3;
        let spec = (-(alpha + d) * t / 2.0).exp()
            * ((d + 2.0 + alpha) * (d * t).exp() + d - 2.0 - alpha)
            / (2.0 * d);
        assert!((damped_oscillator(alpha, 0.0, 0.0, 1.0, 1.0, t).0 - spec).abs() < 1e-14);
    }

    #[test]
    fn series_match_spec_figures() {
        assert!(
            (2.0 * std::f64::consts::PI / harmonic_s2_frequency_series(0.1) - 6.2805655).abs()
                < 1e-7
        );
        assert!(
            (2.0 * std::f64::consts::PI / harmonic_s2_frequency_series(0.5) - 6.2165378).abs()
                < 1e-7
        );
        assert!(
            (van_der_pol_s2_frequency(0.0, 0.3) - harmonic_s2_frequency_series(0.3)).abs() < 1e-6
        );
    }
}
