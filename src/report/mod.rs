//! `reeb report`: which method, which step, which backend gives an accuracy
//! fastest, and where does each method break.
//!
//! * `work-precision`: for every scheme × backend × precision of the scene's
//!   `[report]` table and every `dt` of its axis, the error against the
//!   reference (closed form, or DOP853 at tight tolerance) and the integration
//!   time; the reference integrator itself as a point.
//! * `stability`: over a 2-D grid (typically ε × τ) every cell classified as
//!   accurate, distorted (cycle amplitude or period off by more than a
//!   threshold from the reference's) or diverged (non-finite).
//!
//! This file only names the parts: what both reports share lives in
//! `options` (so that the reports never import this file, which imports them).

mod options;
pub mod stability;
pub mod work_precision;

pub use options::ReportOptions;
pub use stability::{stability, Class};
pub use work_precision::{work_precision, Row};
