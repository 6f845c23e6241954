//! The run's output arrays as views that blocks fill in disjoint rows.

use crate::plan::observations::Observations;

/// Raw view of an output array that blocks fill in disjoint rows.
pub struct Rows<T> {
    ptr: *mut T,
    len: usize,
}
unsafe impl<T: Send> Sync for Rows<T> {}
unsafe impl<T: Send> Send for Rows<T> {}

impl<T> Rows<T> {
    fn new(v: &mut [T]) -> Self {
        Rows {
            ptr: v.as_mut_ptr(),
            len: v.len(),
        }
    }
    /// SAFETY: callers write each index from one block only (rows of distinct
    /// trajectories), and the vector outlives the run.
    #[inline]
    pub fn set(&self, i: usize, v: T) {
        assert!(i < self.len);
        unsafe { *self.ptr.add(i) = v }
    }
}

/// Every output array of an [`Observations`] as disjoint-row views.
pub struct Sink<R> {
    pub final_values: Vec<Rows<R>>,
    pub trajectory: Vec<Rows<R>>,
    pub poincare: Vec<Rows<R>>,
    pub poincare_count: Rows<u32>,
    pub cycle_amplitude: Rows<R>,
    pub cycle_period: Rows<R>,
    pub nonfinite_step: Rows<u32>,
}

impl<R: Send> Sink<R> {
    /// Views of `out`, which must outlive the sink and not move meanwhile.
    pub fn new(out: &mut Observations<R>) -> Self {
        let rows = |v: &mut Vec<(String, Vec<R>)>| -> Vec<Rows<R>> {
            v.iter_mut().map(|(_, x)| Rows::new(x)).collect()
        };
        Sink {
            final_values: rows(&mut out.final_values),
            trajectory: rows(&mut out.trajectory),
            poincare: rows(&mut out.poincare),
            poincare_count: Rows::new(&mut out.poincare_count),
            cycle_amplitude: Rows::new(&mut out.cycle_amplitude),
            cycle_period: Rows::new(&mut out.cycle_period),
            nonfinite_step: Rows::new(&mut out.nonfinite_step),
        }
    }
}
