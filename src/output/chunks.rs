//! The chunks of a streamed run: the unit of work, of memory, of a
//! checkpoint and of a shard. A chunk is a block of the scene's grid that
//! is whole along its trailing axes and a run of `along` values of one axis
//! (`axis`), held at one index of the axes before it; so its trajectories
//! are contiguous rows of every output array (the ensemble's axes lead
//! them), and it is one chunk of a Zarr array chunked `[1, …, 1, along,
//! len, …]`.

use std::ops::Range;

use serde::{Deserialize, Serialize};

/// Largest memory of one chunk's outputs, unless asked otherwise.
pub const DEFAULT_BUDGET: u64 = 1 << 30;

#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Chunks {
    /// The scene's axis lengths.
    pub shape: Vec<usize>,
    /// The axis the chunks cut (0 when there are no axes).
    pub axis: usize,
    /// Values of `axis` per chunk.
    pub along: usize,
}

impl Chunks {
    /// Chunks of about `rows` trajectories at most (at least one trajectory
    /// per chunk): the trailing axes whole as long as they fit.
    pub fn with_rows(shape: &[usize], rows: usize) -> Chunks {
        let rows = rows.max(1);
        let mut axis = shape.len().saturating_sub(1);
        // Move the cut forward while the axes after it still fit.
        while axis > 0 && inner(shape, axis - 1) <= rows {
            axis -= 1;
        }
        let along = match shape.get(axis) {
            Some(len) => (rows / inner(shape, axis)).clamp(1, *len),
            None => 1,
        };
        Chunks {
            shape: shape.to_vec(),
            axis,
            along,
        }
    }

    /// Chunks whose outputs take at most `budget` bytes, for outputs of
    /// `bytes_per_row` bytes per trajectory.
    pub fn with_budget(shape: &[usize], bytes_per_row: u64, budget: u64) -> Chunks {
        let rows = budget / bytes_per_row.max(1);
        Chunks::with_rows(shape, rows.min(usize::MAX as u64) as usize)
    }

    /// Trajectories of the whole grid.
    pub fn rows(&self) -> usize {
        self.shape.iter().product()
    }

    fn len_axis(&self) -> usize {
        self.shape.get(self.axis).copied().unwrap_or(1)
    }

    fn per_run(&self) -> usize {
        self.len_axis().div_ceil(self.along)
    }

    /// Number of chunks.
    pub fn count(&self) -> usize {
        let outer: usize = self.shape[..self.axis.min(self.shape.len())]
            .iter()
            .product();
        outer * self.per_run()
    }

    /// The rows of chunk `k`.
    pub fn range(&self, k: usize) -> Range<usize> {
        let (outer, j) = (k / self.per_run(), k % self.per_run());
        let inner = inner(&self.shape, self.axis);
        let base = outer * self.len_axis();
        let start = base + j * self.along;
        let end = (start + self.along).min(base + self.len_axis());
        start * inner..end * inner
    }

    /// Chunk `k`'s index in the grid of chunks over the scene's axes (its
    /// Zarr chunk key): the index of the axes before `axis`, its run of
    /// `axis`, 0 after.
    pub fn grid_index(&self, k: usize) -> Vec<u64> {
        let (mut outer, j) = (k / self.per_run(), k % self.per_run());
        let mut index = vec![0u64; self.shape.len()];
        for a in (0..self.axis.min(self.shape.len())).rev() {
            index[a] = (outer % self.shape[a]) as u64;
            outer /= self.shape[a];
        }
        if let Some(x) = index.get_mut(self.axis) {
            *x = j as u64;
        }
        index
    }

    /// The shape of a whole chunk over the scene's axes: 1 before `axis`,
    /// `along`, the axes after it whole.
    pub fn chunk_shape(&self) -> Vec<u64> {
        (0..self.shape.len())
            .map(|k| match k.cmp(&self.axis) {
                std::cmp::Ordering::Less => 1,
                std::cmp::Ordering::Equal => self.along as u64,
                std::cmp::Ordering::Greater => self.shape[k] as u64,
            })
            .collect()
    }

    /// The chunks of shard `k` of `n`: contiguous, as even as can be.
    pub fn shard(&self, k: usize, n: usize) -> Range<usize> {
        let c = self.count();
        k * c / n..(k + 1) * c / n
    }

    /// The trajectories of a chunk of the largest kind.
    pub fn largest(&self) -> usize {
        self.along * inner(&self.shape, self.axis)
    }
}

/// Trajectories per value of `axis`: the product of the axes after it.
fn inner(shape: &[usize], axis: usize) -> usize {
    shape.get(axis + 1..).map_or(1, |s| s.iter().product())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every row in exactly one chunk, in order.
    fn tiles(c: &Chunks) {
        let mut next = 0;
        for k in 0..c.count() {
            let r = c.range(k);
            assert_eq!(r.start, next, "{c:?} chunk {k}");
            assert!(!r.is_empty() && r.len() <= c.largest());
            next = r.end;
        }
        assert_eq!(next, c.rows(), "{c:?}");
    }

    #[test]
    fn chunks_tile_the_grid_as_whole_trailing_axes() {
        for (shape, rows) in [
            (vec![256, 256], 1000),
            (vec![256, 256], 256),
            (vec![256, 256], 100),
            (vec![7, 5, 3], 16),
            (vec![7, 5, 3], 10_000),
            (vec![10], 3),
            (vec![], 5),
            (vec![3, 1_000_000], 200_000),
        ] {
            let c = Chunks::with_rows(&shape, rows);
            tiles(&c);
            assert!(c.largest() <= rows.max(1) || c.along == 1, "{c:?}");
        }
        let c = Chunks::with_rows(&[256, 256], 1000);
        assert_eq!((c.axis, c.along, c.count()), (0, 3, 86));
        assert_eq!(c.range(85), 85 * 3 * 256..256 * 256);
    }

    #[test]
    fn the_grid_index_is_where_the_chunk_starts() {
        for (shape, rows) in [
            (vec![6, 7, 2], 5),
            (vec![4, 9], 4),
            (vec![5], 2),
            (vec![3, 4, 5], 60),
        ] {
            let c = Chunks::with_rows(&shape, rows);
            let whole = c.chunk_shape();
            for k in 0..c.count() {
                let mut start = c.range(k).start;
                let mut at = vec![0u64; shape.len()];
                for a in (0..shape.len()).rev() {
                    at[a] = (start % shape[a]) as u64 / whole[a];
                    start /= shape[a];
                }
                assert_eq!(c.grid_index(k), at, "{c:?} chunk {k}");
            }
        }
    }

    #[test]
    fn shards_split_the_chunks() {
        let c = Chunks::with_rows(&[10, 10], 10);
        let mut next = 0;
        for k in 0..4 {
            let s = c.shard(k, 4);
            assert_eq!(s.start, next);
            next = s.end;
        }
        assert_eq!(next, c.count());
    }
}
