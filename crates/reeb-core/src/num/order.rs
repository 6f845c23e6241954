//! Values in increasing order, without sorting what is in order already.

use std::borrow::Cow;

use rayon::prelude::*;

/// `values` in increasing (total) order: as they are where they already
/// are (a `linspace`, a `logspace`: the axes of millions of values),
/// reversed where they decrease, else sorted on every core.
pub fn ascending(values: &[f64]) -> Cow<'_, [f64]> {
    let le = |a: &f64, b: &f64| a.total_cmp(b).is_le();
    if values.is_sorted_by(le) {
        Cow::Borrowed(values)
    } else if values.is_sorted_by(|a, b| le(b, a)) {
        Cow::Owned(values.iter().rev().copied().collect())
    } else {
        let mut v = values.to_vec();
        v.par_sort_unstable_by(f64::total_cmp);
        Cow::Owned(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_order_is_borrowed_and_the_rest_sorted() {
        let up = [0.0, 1.0, 1.0, 2.5];
        assert!(matches!(ascending(&up), Cow::Borrowed(_)));
        let down = [2.5, 1.0, 1.0, 0.0];
        assert_eq!(&*ascending(&down), &up);
        let mixed = [1.0, 2.5, 0.0, 1.0, -0.0];
        assert_eq!(&*ascending(&mixed), &[-0.0, 0.0, 1.0, 1.0, 2.5]);
        assert!(ascending(&mixed)[0].is_sign_negative());
        assert!(ascending(&[]).is_empty());
    }
}
