//! Mechanical systems with Rayleigh-type dissipation (SPEC §2.1):
//! `H = |p|²/2 + V(q, t) + f(t) s`, pieces `A` (f s), `B` (V), `C` (|p|²/2),
//! and the comparison integrators built on `V'`, `V` and `f` (SPEC §3).

#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

crate::shared_fns! {
    /// Exact flows of the mechanical pieces, per component.
    trait MechanicalFlows, wgsl MECHANICAL_FLOWS_WGSL;

    /// Piece A over τ: `x ← x e^{−τ f}` for x = p and x = s.
    fn mech_scale(x: R, tau: R, f: R) -> R {
        return x * R::exp_r(-(tau * f));
    }
    /// Piece B over τ: `p ← p − τ ∂V`, `s ← s − τ V`.
    fn mech_kick(x: R, tau: R, dv: R) -> R {
        return x - tau * dv;
    }
    /// Piece C over τ on a position: `q ← q + τ p`.
    fn mech_drift(q: R, tau: R, p: R) -> R {
        return q + tau * p;
    }
    /// Piece C over τ on the action: `s ← s + τ |p|²/2`.
    fn mech_drift_s(s: R, tau: R, p2: R) -> R {
        return s + tau * (0.5 * p2);
    }
    /// Classical RK4 update of one component from its four slopes.
    fn rk4_combine(x: R, tau: R, k1: R, k2: R, k3: R, k4: R) -> R {
        return x + tau / 6.0 * (k1 + 2.0 * (k2 + k3) + k4);
    }
}

crate::model_ops! {
    /// Ops common to the one-dimensional mechanical models.
    trait Mechanical1dOps, wgsl MECHANICAL_1D_WGSL, lanes mechanical_1d_lanes;

    /// Piece C on q.
    fn mech1_c_q(q: &mut R, p: R, tau: R) {
        *q = R::mech_drift(*q, tau, p);
    }
    /// Piece C on s.
    fn mech1_c_s(s: &mut R, p: R, tau: R) {
        *s = R::mech_drift_s(*s, tau, p * p);
    }
    /// Piece A on p with the time-dependent damping f(t).
    fn mech1_a_p(p: &mut R, tau: R, damping: R) {
        *p = R::mech_scale(*p, tau, damping);
    }
    /// Piece A on s with the time-dependent damping f(t).
    fn mech1_a_s(s: &mut R, tau: R, damping: R) {
        *s = R::mech_scale(*s, tau, damping);
    }
}

/// Generates, from a model's `mech` function (`V'(q,t)`, `V(q,t)`, `f(t)`),
/// its vector field and the comparison integrators of SPEC §3 on `(q, p, s)`:
/// RK4, the leapfrog of seed 000 §2 with the damping in the acceleration, and
/// the contact variational integrators of first and second order. Both
/// evaluate `f` at the step midpoint (so Lane–Emden's `f = 2/t` is never
/// evaluated at t = 0) and `V'`, `V` at the step ends, which carries forcing
/// through `V(q, t)` exactly as SPEC §3 adds `F(t_j)`, `F(t_{j+1})`.
#[macro_export]
macro_rules! mechanical_1d_methods {
    (
        ops trait $tr:ident, wgsl $wg:ident, lanes $lm:ident;
        mech $mech:ident, field $field:ident, rk4 $rk4:ident, leapfrog $lf:ident,
        variational1 $v1:ident, variational2 $v2:ident $(, regular_at_zero $reg:ident)?;
        params [$($par:ident),* $(,)?]
    ) => {
        $crate::model_ops! {
            /// Vector field and comparison integrators.
            trait $tr, wgsl $wg, lanes $lm;

            /// The contact vector field at (q, p, s, t).
            fn $field(q: R, p: R, s: R, t: R, $($par: R,)* dq: &mut R, dp: &mut R, ds: &mut R) {
                let mut dv: R = 0.0;
                let mut v: R = 0.0;
                let mut f: R = 0.0;
                R::$mech(q, t, $($par,)* &mut dv, &mut v, &mut f);
                // `$reg` replaces f·p by its limit where f is singular (t = 0).
                let mut fp: R = f * p;
                let mut fs: R = f * s;
                $( fp = R::$reg(fp, dv, t); fs = R::$reg(fs, v, t); )?
                *dq = p;
                *dp = -dv - fp;
                *ds = 0.5 * p * p - v - fs;
            }
            /// Classical fourth-order Runge–Kutta step from t over τ.
            fn $rk4(q: &mut R, p: &mut R, s: &mut R, t: R, tau: R, $($par: R),*) {
                let hh: R = 0.5 * tau;
                let mut k1q: R = 0.0;
                let mut k1p: R = 0.0;
                let mut k1s: R = 0.0;
                R::$field(*q, *p, *s, t, $($par,)* &mut k1q, &mut k1p, &mut k1s);
                let mut k2q: R = 0.0;
                let mut k2p: R = 0.0;
                let mut k2s: R = 0.0;
                R::$field(*q + hh * k1q, *p + hh * k1p, *s + hh * k1s, t + hh, $($par,)* &mut k2q, &mut k2p, &mut k2s);
                let mut k3q: R = 0.0;
                let mut k3p: R = 0.0;
                let mut k3s: R = 0.0;
                R::$field(*q + hh * k2q, *p + hh * k2p, *s + hh * k2s, t + hh, $($par,)* &mut k3q, &mut k3p, &mut k3s);
                let mut k4q: R = 0.0;
                let mut k4p: R = 0.0;
                let mut k4s: R = 0.0;
                R::$field(*q + tau * k3q, *p + tau * k3p, *s + tau * k3s, t + tau, $($par,)* &mut k4q, &mut k4p, &mut k4s);
                *q = R::rk4_combine(*q, tau, k1q, k2q, k3q, k4q);
                *p = R::rk4_combine(*p, tau, k1p, k2p, k3p, k4p);
                *s = R::rk4_combine(*s, tau, k1s, k2s, k3s, k4s);
            }
            /// Leapfrog (Störmer–Verlet) with the damping in the acceleration,
            /// seed 000 eq. after (20); the action by the trapezoidal Lagrangian.
            fn $lf(q: &mut R, p: &mut R, s: &mut R, t: R, tau: R, $($par: R),*) {
                let mut dv0: R = 0.0;
                let mut v0: R = 0.0;
                let mut fa: R = 0.0;
                R::$mech(*q, t, $($par,)* &mut dv0, &mut v0, &mut fa);
                let mut dvm: R = 0.0;
                let mut vm: R = 0.0;
                let mut fm: R = 0.0;
                R::$mech(*q, t + 0.5 * tau, $($par,)* &mut dvm, &mut vm, &mut fm);
                let ph: R = (*p - 0.5 * tau * dv0) / (1.0 + 0.5 * tau * fm);
                let qn: R = *q + tau * ph;
                let mut dv1: R = 0.0;
                let mut v1: R = 0.0;
                let mut fb: R = 0.0;
                R::$mech(qn, t + tau, $($par,)* &mut dv1, &mut v1, &mut fb);
                *s = (*s * (1.0 - 0.5 * tau * fm) + tau * (0.5 * ph * ph - 0.5 * (v0 + v1)))
                    / (1.0 + 0.5 * tau * fm);
                *p = ph - 0.5 * tau * (dv1 + fm * ph);
                *q = qn;
            }
            /// Contact variational integrator of first order (seed 000, example 1).
            fn $v1(q: &mut R, p: &mut R, s: &mut R, t: R, tau: R, $($par: R),*) {
                let mut dv0: R = 0.0;
                let mut v0: R = 0.0;
                let mut fa: R = 0.0;
                R::$mech(*q, t, $($par,)* &mut dv0, &mut v0, &mut fa);
                let mut dvm: R = 0.0;
                let mut vm: R = 0.0;
                let mut fm: R = 0.0;
                R::$mech(*q, t + 0.5 * tau, $($par,)* &mut dvm, &mut vm, &mut fm);
                let c: R = 1.0 - tau * fm;
                let qn: R = *q + tau * c * *p - 0.5 * tau * tau * dv0;
                let mut dv1: R = 0.0;
                let mut v1: R = 0.0;
                let mut fb: R = 0.0;
                R::$mech(qn, t + tau, $($par,)* &mut dv1, &mut v1, &mut fb);
                let vel: R = (qn - *q) / tau;
                *s = *s * c + tau * (0.5 * vel * vel - 0.5 * (v0 + v1));
                *p = c * *p - 0.5 * tau * (dv0 + dv1);
                *q = qn;
            }
            /// Contact variational integrator of second order, "contact
            /// leapfrog" (seed 000, examples 2 and 6).
            fn $v2(q: &mut R, p: &mut R, s: &mut R, t: R, tau: R, $($par: R),*) {
                let mut dv0: R = 0.0;
                let mut v0: R = 0.0;
                let mut fa: R = 0.0;
                R::$mech(*q, t, $($par,)* &mut dv0, &mut v0, &mut fa);
                let mut dvm: R = 0.0;
                let mut vm: R = 0.0;
                let mut fm: R = 0.0;
                R::$mech(*q, t + 0.5 * tau, $($par,)* &mut dvm, &mut vm, &mut fm);
                let c: R = 1.0 - 0.5 * tau * fm;
                let d: R = 1.0 + 0.5 * tau * fm;
                let qn: R = *q + tau * c * *p - 0.5 * tau * tau * dv0;
                let mut dv1: R = 0.0;
                let mut v1: R = 0.0;
                let mut fb: R = 0.0;
                R::$mech(qn, t + tau, $($par,)* &mut dv1, &mut v1, &mut fb);
                let vel: R = (qn - *q) / tau;
                *s = (*s * c + tau * (0.5 * vel * vel - 0.5 * (v0 + v1))) / d;
                *p = (c * *p - 0.5 * tau * (dv0 + dv1)) / d;
                *q = qn;
            }
        }
    };
}
