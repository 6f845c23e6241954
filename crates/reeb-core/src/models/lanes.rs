//! A block of trajectories in structure-of-arrays form.
//!
//! Every name an op's shared function can take as an argument is a field of
//! [`Lanes`]: state variables, their derivatives, time, step, time terms and
//! model parameters. An op's lane loop binds its arguments to these fields by
//! name, so the CPU backend needs no hand-written wiring per model, and the GPU
//! kernel declares locals with the same names.

use crate::num::precision::Real;

/// Trajectories per block. Large enough to amortise the per-op dispatch,
/// small enough that the arrays a step touches stay in L1.
pub const LANES: usize = 64;

/// Whether an op argument of type `ty` (as written) is one the op writes.
pub const fn written(ty: &str) -> bool {
    !ty.is_empty() && ty.as_bytes()[0] == b'&'
}

/// The lane loop of one op.
pub type LaneFn<R> = fn(&mut Lanes<R>);

/// One op applied to a single trajectory.
pub type ScalarFn<R> = fn(&mut Lane<R>);

/// Binds a lane element to a shared function's argument: by value for `R`,
/// by reference for `&mut R`. The argument's type chooses the impl.
pub trait Bind<'a, R> {
    fn bind(x: &'a mut R) -> Self;
}

impl<'a, R: Copy> Bind<'a, R> for R {
    #[inline(always)]
    fn bind(x: &'a mut R) -> R {
        *x
    }
}

impl<'a, R> Bind<'a, R> for &'a mut R {
    #[inline(always)]
    fn bind(x: &'a mut R) -> &'a mut R {
        x
    }
}

macro_rules! define_lanes {
    ($( $(#[$m:meta])* $f:ident ),* $(,)?) => {
        /// One block of [`LANES`] trajectories; see the module documentation.
        /// `repr(C)` with one field type: the layout of `[[R; LANES]; COUNT]`,
        /// which [`Lanes::at`] relies on; on cache lines as [`LaneArrays`].
        #[repr(C, align(64))]
        pub struct Lanes<R> {
            $( $(#[$m])* pub $f: [R; LANES], )*
        }

        /// Every name an op may bind, in declaration order.
        pub const NAMES: &[&str] = &[$(stringify!($f)),*];
        /// Number of lane arrays.
        pub const COUNT: usize = NAMES.len();

        /// Position of the lane array called `name` (for [`Lanes::at`]).
        pub fn index_of(name: &str) -> Option<usize> {
            NAMES.iter().position(|n| *n == name)
        }

        /// One trajectory of a block: the scalar twin of [`Lanes`], with the
        /// same field names, which scalar ops bind by name. `repr(C)` with
        /// one field type, as [`Lanes`]: [`Lane::at`] relies on it.
        #[derive(Debug, Clone, Copy, Default)]
        #[repr(C)]
        pub struct Lane<R> {
            $( $(#[$m])* pub $f: R, )*
        }

        impl<R: Real> Lane<R> {
            /// The value at position `k` of [`NAMES`].
            #[inline(always)]
            pub fn at(&self, k: usize) -> R {
                assert!(k < COUNT);
                // SAFETY: repr(C) struct of COUNT fields of type R, no padding.
                unsafe { *(self as *const Self as *const R).add(k) }
            }
            /// The value at position `k` of [`NAMES`], mutable.
            #[inline(always)]
            pub fn at_mut(&mut self, k: usize) -> &mut R {
                assert!(k < COUNT);
                // SAFETY: as in `at`; the &mut self borrow covers the whole struct.
                unsafe { &mut *(self as *mut Self as *mut R).add(k) }
            }
            /// Trajectory `i` of a block (loads the compiler finds unused are dropped).
            #[inline(always)]
            pub fn gather(l: &Lanes<R>, i: usize) -> Lane<R> {
                Lane { $( $f: l.$f[i], )* }
            }
            /// Writes the state variables back into lane `i` of a block.
            #[inline(always)]
            pub fn scatter_state(&self, l: &mut Lanes<R>, i: usize) {
                l.q[i] = self.q;
                l.p[i] = self.p;
                l.s[i] = self.s;
                l.q1[i] = self.q1;
                l.q2[i] = self.q2;
                l.p1[i] = self.p1;
                l.p2[i] = self.p2;
                l.q3[i] = self.q3;
                l.q4[i] = self.q4;
                l.p3[i] = self.p3;
                l.p4[i] = self.p4;
            }
            /// Writes the time and the time terms back into lane `i` of a
            /// block (a stage's time pass, for the pieces that follow).
            #[inline(always)]
            pub fn scatter_time(&self, l: &mut Lanes<R>, i: usize) {
                l.t[i] = self.t;
                l.forcing[i] = self.forcing;
                l.damping[i] = self.damping;
                l.pref[i] = self.pref;
                l.cw[i] = self.cw;
                l.sw[i] = self.sw;
            }
            /// The scalar named `name`.
            pub fn get(&self, name: &str) -> Option<R> {
                match name {
                    $( stringify!($f) => Some(self.$f), )*
                    _ => None,
                }
            }
            /// The scalar named `name`, mutable.
            pub fn get_mut(&mut self, name: &str) -> Option<&mut R> {
                match name {
                    $( stringify!($f) => Some(&mut self.$f), )*
                    _ => None,
                }
            }
        }

        impl<R: Real> Lanes<R> {
            pub fn boxed() -> Box<Self> {
                Box::new(Self { $( $f: [R::default(); LANES], )* })
            }
            /// The lane array at position `k` of [`NAMES`].
            #[inline(always)]
            pub fn at(&self, k: usize) -> &[R; LANES] {
                assert!(k < COUNT);
                // SAFETY: repr(C) struct of COUNT fields of type [R; LANES], no padding.
                unsafe { &*(self as *const Self as *const [R; LANES]).add(k) }
            }
            /// The lane array at position `k` of [`NAMES`], mutable.
            #[inline(always)]
            pub fn at_mut(&mut self, k: usize) -> &mut [R; LANES] {
                assert!(k < COUNT);
                // SAFETY: as in `at`; the &mut self borrow covers the whole struct.
                unsafe { &mut *(self as *mut Self as *mut [R; LANES]).add(k) }
            }
            /// Makes trajectory `to` a copy of trajectory `from`, every field.
            pub fn copy_lane(&mut self, from: usize, to: usize) {
                $( self.$f[to] = self.$f[from]; )*
            }
            /// Every lane array, one after the other (a snapshot's view).
            pub fn as_slice(&self) -> &[R] {
                // SAFETY: as in `at`: COUNT arrays of LANES values, no padding.
                unsafe { std::slice::from_raw_parts(self as *const Self as *const R, COUNT * LANES) }
            }
            /// [`Self::as_slice`], mutable.
            pub fn as_mut_slice(&mut self) -> &mut [R] {
                // SAFETY: as in `as_slice`; the &mut self borrow covers the whole struct.
                unsafe { std::slice::from_raw_parts_mut(self as *mut Self as *mut R, COUNT * LANES) }
            }
            /// The lane array called `name`.
            pub fn field(&self, name: &str) -> Option<&[R; LANES]> {
                match name {
                    $( stringify!($f) => Some(&self.$f), )*
                    _ => None,
                }
            }
            /// The lane array called `name`, mutable.
            pub fn field_mut(&mut self, name: &str) -> Option<&mut [R; LANES]> {
                match name {
                    $( stringify!($f) => Some(&mut self.$f), )*
                    _ => None,
                }
            }
        }
    };
}

define_lanes! {
    // State variables.
    q, p, s, q1, q2, p1, p2, q3, q4, p3, p4,
    // Their time derivatives (outputs of the models' vector fields).
    dq, dp, ds, dq1, dq2, dp1, dp2, dq3, dq4, dp3, dp4,
    /// Time at which the current stage evaluates time-dependent terms.
    t,
    /// Signed sub-step of the current op.
    tau,
    /// Step size of each trajectory.
    dt,
    /// Initial time of each trajectory.
    t0,
    /// Stroboscopic section: period and phase (time of the first sample after t0).
    strobe_period,
    strobe_phase,
    // Time terms, evaluated once per stage by a model's time op.
    forcing, damping, pref, cw, sw,
    // Model parameters, by their scene names (SPEC §2.4).
    alpha, forcing_amplitude, forcing_frequency, epsilon, theta, index, eccentricity,
    lambda, omega, tidal_k, tidal_eta, gamma, r,
    // Derived parameters: spin–orbit Fourier weights, Liénard polynomial coefficients.
    a1, a2, a3, a4, a5, a6, a7, a8, a9,
    b1, b2, b3, b4, b5, b6, b7, b8, b9,
    f0, f1, f2, f3, f4, f5, f6, f7, f8, f9,
    g0, g1, g2, g3, g4, g5, g6, g7, g8, g9,
    // Parameters of formula models, by slot (`models/formula.rs`).
    k0, k1, k2, k3, k4, k5, k6, k7, k8, k9, k10, k11, k12, k13, k14, k15,
}

impl<R: Real> Lanes<R> {
    /// Whether some lane array of `fields` (indices of [`NAMES`]) holds a
    /// non-finite value: one vectorised pass per array with an OR-reduction.
    #[inline(always)]
    pub fn any_nonfinite(&self, fields: &[usize]) -> bool {
        let mut any = false;
        for &k in fields {
            for x in self.at(k) {
                any |= !x.finite();
            }
        }
        any
    }
}

const _: () = assert!(std::mem::size_of::<Lanes<f64>>() == COUNT * LANES * 8);
const _: () = assert!(std::mem::size_of::<Lane<f64>>() == COUNT * 8);
const _: () = assert!(std::mem::size_of::<Lane<f32>>() == COUNT * 4);
const _: () = assert!(std::mem::size_of::<Lanes<f32>>() == COUNT * LANES * 4);

/// A lane array on cache lines of its own.
#[repr(C, align(64))]
#[derive(Clone, Copy)]
struct Line<R>([R; LANES]);

/// Lane arrays aligned to cache lines, used as `[[R; LANES]]`: the block
/// interpreter and the observers read and write lane arrays whole with
/// vector instructions, which take half as long again when each straddles
/// two lines, as in a `Vec<[R; LANES]>` (aligned to `R` only).
#[derive(Clone)]
pub struct LaneArrays<R> {
    lines: Vec<Line<R>>,
}

impl<R: Copy> LaneArrays<R> {
    /// `n` arrays of `value`.
    pub fn filled(n: usize, value: R) -> Self {
        LaneArrays {
            lines: vec![Line([value; LANES]); n],
        }
    }
}

impl<R: Copy> FromIterator<[R; LANES]> for LaneArrays<R> {
    fn from_iter<I: IntoIterator<Item = [R; LANES]>>(arrays: I) -> Self {
        LaneArrays {
            lines: arrays.into_iter().map(Line).collect(),
        }
    }
}

impl<R> std::ops::Deref for LaneArrays<R> {
    type Target = [[R; LANES]];
    fn deref(&self) -> &[[R; LANES]] {
        const { assert!(std::mem::size_of::<Line<R>>() == std::mem::size_of::<[R; LANES]>()) };
        // SAFETY: `Line<R>` is `repr(C)` around one `[R; LANES]`, of the same
        // size (asserted: a multiple of the alignment), so a slice of lines
        // is a slice of arrays.
        unsafe { std::slice::from_raw_parts(self.lines.as_ptr().cast(), self.lines.len()) }
    }
}

impl<R> std::ops::DerefMut for LaneArrays<R> {
    fn deref_mut(&mut self) -> &mut [[R; LANES]] {
        const { assert!(std::mem::size_of::<Line<R>>() == std::mem::size_of::<[R; LANES]>()) };
        // SAFETY: as in `deref`.
        unsafe { std::slice::from_raw_parts_mut(self.lines.as_mut_ptr().cast(), self.lines.len()) }
    }
}

/// Declares a model's ops: shared functions (see [`crate::num::dsl`]) whose
/// arguments are lane names, plus, for the CPU, a lane loop per op (`lanes`
/// module) and its one-trajectory twin (`lanes::scalar`), found by name.
///
/// `model_ops! { trait Name, wgsl CONST, lanes module; fn ..(..) {..} ... }`
#[macro_export]
macro_rules! model_ops {
    (
        $(#[$tmeta:meta])*
        trait $tr:ident, wgsl $wg:ident, lanes $lm:ident;
        $(
            $(#[$fmeta:meta])*
            fn $name:ident ( $($arg:ident : $aty:ty),* $(,)? ) $body:block
        )*
    ) => {
        $crate::shared_fns! {
            $(#[$tmeta])*
            trait $tr, wgsl $wg;
            $( $(#[$fmeta])* fn $name($($arg: $aty),*) $body )*
        }
        /// Lane loops, one per op: each applies its shared function to every
        /// lane of a block, binding every argument to the lane array of the
        /// same name (the GPU kernel binds them to locals of the same name).
        pub mod $lm {
            #[allow(unused_imports)]
            use super::*;
            use $crate::models::lanes::{Bind, LaneFn, Lanes, LANES};
            use $crate::num::precision::Real;
            $(
                #[allow(clippy::needless_range_loop)]
                pub fn $name<R: Real + $tr>(l: &mut Lanes<R>) {
                    for i in 0..LANES {
                        <R as $tr>::$name($( Bind::bind(&mut l.$arg[i]) ),*);
                    }
                }
            )*
            /// The lane loop of the op called `name`.
            pub fn lookup<R: Real + $tr>(name: &str) -> Option<LaneFn<R>> {
                match name {
                    $( stringify!($name) => Some($name::<R> as LaneFn<R>), )*
                    _ => None,
                }
            }
            /// The arguments of the op called `name`: lane names, and
            /// whether the op writes them.
            pub fn args(name: &str) -> Option<&'static [(&'static str, bool)]> {
                match name {
                    $( stringify!($name) => {
                        const ARGS: &[(&str, bool)] =
                            &[$( (stringify!($arg), $crate::models::lanes::written(stringify!($aty))) ),*];
                        Some(ARGS)
                    } )*
                    _ => None,
                }
            }

            /// Each op's arguments copied from one trajectory to another:
            /// a block's lanes take the time terms its first lane evaluated
            /// (`Pieces::share_time`).
            pub mod share {
                use $crate::models::lanes::Lane;
                $(
                    #[inline(always)]
                    pub fn $name<R: Copy>(x: &mut Lane<R>, from: &Lane<R>) {
                        $( x.$arg = from.$arg; )*
                    }
                )*
            }

            /// The same ops on one trajectory, binding the fields of a [`Lane`].
            pub mod scalar {
                #[allow(unused_imports)]
                use super::super::*;
                use $crate::models::lanes::{Bind, Lane, ScalarFn};
                use $crate::num::precision::Real;
                $(
                    #[inline(always)]
                    pub fn $name<R: Real + super::super::$tr>(x: &mut Lane<R>) {
                        <R as $tr>::$name($( Bind::bind(&mut x.$arg) ),*);
                    }
                )*
                /// The scalar op called `name`.
                pub fn lookup<R: Real + super::super::$tr>(name: &str) -> Option<ScalarFn<R>> {
                    match name {
                        $( stringify!($name) => Some($name::<R> as ScalarFn<R>), )*
                        _ => None,
                    }
                }
            }
        }
    }
}

/// Declares, in a model's file, everything the registry needs from its
/// shared functions: `pub trait Ops` (every trait the model's ops call, so
/// that `R: Ops` can run them) and the lookups of its ops by name.
///
/// `model_lanes! { traits [A, B]; lanes [a_lanes, super::other::b_lanes] }`
#[macro_export]
macro_rules! model_lanes {
    (traits [$($tr:path),* $(,)?]; lanes [$($($lm:ident)::+),* $(,)?] $(;)?) => {
        /// Every shared-function trait this model's ops call.
        pub trait Ops: $crate::num::precision::Real $(+ $tr)* {}
        impl<T: $crate::num::precision::Real $(+ $tr)*> Ops for T {}
        /// The lane loop of this model's op `name`.
        pub fn lane_fn<R: Ops>(name: &str) -> Option<$crate::models::lanes::LaneFn<R>> {
            None$(.or_else(|| $($lm)::+::lookup::<R>(name)))*
        }
        /// The arguments of this model's op `name` (lane name, written).
        pub fn op_args(name: &str) -> Option<&'static [(&'static str, bool)]> {
            None$(.or_else(|| $($lm)::+::args(name)))*
        }
        /// The one-trajectory op `name` of this model.
        pub fn scalar_fn<R: Ops>(name: &str) -> Option<$crate::models::lanes::ScalarFn<R>> {
            None$(.or_else(|| $($lm)::+::scalar::lookup::<R>(name)))*
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lane_arrays_are_arrays_on_cache_lines() {
        let mut a = LaneArrays::filled(3, 1.5f32);
        a[1][5] = 2.0;
        assert_eq!(
            (a.len(), a[1][5], a[1][4], a[2][LANES - 1]),
            (3, 2.0, 1.5, 1.5)
        );
        let b: LaneArrays<f64> = (0..5).map(|k| [k as f64; LANES]).collect();
        assert_eq!(b[4], [4.0; LANES]);
        let addresses = a.iter().map(|x| x.as_ptr() as usize);
        assert!(addresses
            .chain(b.iter().map(|x| x.as_ptr() as usize))
            .all(|p| p % 64 == 0));
        assert_eq!(std::ptr::addr_of!(*Lanes::<f32>::boxed()) as usize % 64, 0);
    }
}
