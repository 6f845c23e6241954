//! References to measure errors against: an adaptive DOP853 integrator of a
//! model's vector field, the truth of a plan (closed forms where a model
//! has one, DOP853 otherwise), and the flow's Lyapunov exponents from its
//! variational equations.

pub mod dop853;
pub mod truth;
pub mod variational;
