//! References to measure errors against: an adaptive DOP853 integrator of a
//! model's vector field, and the truth of a plan (closed forms where a model
//! has one, DOP853 otherwise).

pub mod dop853;
pub mod truth;
