//! One label per attractor across an ensemble, from what each orbit ends on
//! (`plan::recurrence`): periodic orbits on the same point set within
//! tolerance share a label whatever their phase on it; aperiodic ones share
//! a label when their samples share cells of a coarse grid; escapes (a stop
//! condition, a non-finite state) are −1. Labels 0, 1, … go by basin size.
//! Also the basin fractions with their standard errors, and the basin
//! entropy of a grid of initial conditions (Daza et al. 2016).

use std::collections::HashMap;

use crate::plan::recurrence::Recurrence;

/// What kind of attractor an orbit ends on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    FixedPoint,
    Periodic,
    Aperiodic,
    Escape,
}

/// One orbit's end: its kind, its period (0 unless periodic) and its last
/// samples (one per phase for a periodic orbit, `dim` components each).
#[derive(Debug, Clone, PartialEq)]
pub struct End {
    pub kind: Kind,
    pub period: usize,
    pub points: Vec<f64>,
}

/// One attractor of the ensemble: the first orbit found on it stands for it.
#[derive(Debug, Clone, PartialEq)]
pub struct Attractor {
    pub label: i32,
    pub kind: Kind,
    pub period: usize,
    pub points: Vec<f64>,
    pub count: usize,
}

/// Every orbit's label, and the attractors by label (escape last, as −1).
#[derive(Debug, Clone, PartialEq)]
pub struct Labelling {
    pub labels: Vec<i32>,
    pub attractors: Vec<Attractor>,
}

/// Cells per component of the grid on which aperiodic orbits' samples meet.
const APERIODIC_CELLS: usize = 16;

/// Labels every orbit; see the module documentation.
pub fn label(ends: &[End], r: &Recurrence) -> Labelling {
    let mut group = vec![usize::MAX; ends.len()];
    let mut groups: Vec<(Kind, usize, usize)> = vec![]; // kind, period, first orbit
    periodic_groups(ends, r, &mut group, &mut groups);
    aperiodic_groups(ends, r, &mut group, &mut groups);
    let mut counts = vec![0usize; groups.len()];
    for &g in group.iter().filter(|g| **g != usize::MAX) {
        counts[g] += 1;
    }
    // Largest basin first; ties by kind, period, then the first orbit.
    let mut order: Vec<usize> = (0..groups.len()).collect();
    order.sort_by_key(|&g| {
        (
            std::cmp::Reverse(counts[g]),
            groups[g].0,
            groups[g].1,
            groups[g].2,
        )
    });
    let mut label_of = vec![0i32; groups.len()];
    let mut attractors = vec![];
    for (label, &g) in order.iter().enumerate() {
        label_of[g] = label as i32;
        let (kind, period, first) = groups[g];
        attractors.push(Attractor {
            label: label as i32,
            kind,
            period,
            points: ends[first].points.clone(),
            count: counts[g],
        });
    }
    labelled(&group, &label_of, attractors)
}

/// Each orbit's label from its group's (`usize::MAX`: none, an escape:
/// −1), with the escapes' entry after the attractors when there are any.
fn labelled(group: &[usize], label_of: &[i32], mut attractors: Vec<Attractor>) -> Labelling {
    let labels: Vec<i32> = group
        .iter()
        .map(|&g| if g == usize::MAX { -1 } else { label_of[g] })
        .collect();
    let escaped = labels.iter().filter(|l| **l < 0).count();
    if escaped > 0 {
        attractors.push(Attractor {
            label: -1,
            kind: Kind::Escape,
            period: 0,
            points: vec![],
            count: escaped,
        });
    }
    Labelling { labels, attractors }
}

/// The largest distance from a point of `a` to the nearest point of `b`,
/// and back (the Hausdorff distance), of two sets of `dim`-component points.
pub fn hausdorff(a: &[f64], b: &[f64], r: &Recurrence) -> f64 {
    let d = r.dim().max(1);
    let one_way = |a: &[f64], b: &[f64]| {
        a.chunks(d)
            .map(|x| {
                b.chunks(d)
                    .map(|y| r.distance(x, y))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    };
    one_way(a, b).max(one_way(b, a))
}

/// The cell of a point's first two components on a grid of `size`, angles
/// taken into [0, P) and their cells counted modulo the circle's.
fn cell(x: &[f64], r: &Recurrence, size: f64) -> [i64; 2] {
    let mut c = [0i64; 2];
    for (k, c) in c.iter_mut().enumerate().take(r.dim().min(2)) {
        *c = (r.coordinate(x, k) / size).floor() as i64;
    }
    c
}

/// The neighbouring cells of `c` (itself included), wrapping around angles.
fn around(c: [i64; 2], r: &Recurrence, size: f64) -> Vec<[i64; 2]> {
    let span = |k: usize| -> Vec<i64> {
        if k >= r.dim() {
            return vec![0];
        }
        let near = [c[k] - 1, c[k], c[k] + 1];
        match r.wrap[k] {
            Some(p) => {
                let cells = (p / size).ceil() as i64;
                let mut v: Vec<i64> = near.iter().map(|i| i.rem_euclid(cells)).collect();
                v.dedup();
                v
            }
            None => near.to_vec(),
        }
    };
    let mut out = vec![];
    for i in span(0) {
        for j in span(1) {
            out.push([i, j]);
        }
    }
    out
}

/// Groups fixed points and periodic orbits: same period, point sets within
/// twice the tolerance (each within tolerance of the same cycle). A grid of
/// cells of that size finds the candidates.
fn periodic_groups(
    ends: &[End],
    r: &Recurrence,
    group: &mut [usize],
    groups: &mut Vec<(Kind, usize, usize)>,
) {
    let (d, near) = (r.dim().max(1), 2.0 * r.tolerance);
    let size = 2.0 * near;
    let mut by_cell: HashMap<(usize, [i64; 2]), Vec<usize>> = HashMap::new();
    for (i, e) in ends.iter().enumerate() {
        if !matches!(e.kind, Kind::FixedPoint | Kind::Periodic) {
            continue;
        }
        let first = &e.points[..d];
        let candidates = around(cell(first, r, size), r, size);
        let found = candidates.iter().find_map(|c| {
            by_cell.get(&(e.period, *c))?.iter().copied().find(|&g| {
                let rep = &ends[groups[g].2];
                hausdorff(&e.points, &rep.points, r) <= near
            })
        });
        let g = found.unwrap_or_else(|| {
            groups.push((e.kind, e.period, i));
            let g = groups.len() - 1;
            for x in e.points.chunks(d) {
                let list = by_cell.entry((e.period, cell(x, r, size))).or_default();
                if !list.contains(&g) {
                    list.push(g);
                }
            }
            g
        });
        group[i] = g;
    }
}

/// Groups aperiodic orbits whose samples share a cell of a coarse grid
/// over where they all lie (`APERIODIC_CELLS` per component, the first
/// three components): union–find over cells.
fn aperiodic_groups(
    ends: &[End],
    r: &Recurrence,
    group: &mut [usize],
    groups: &mut Vec<(Kind, usize, usize)>,
) {
    let d = r.dim().max(1);
    let which: Vec<usize> = (0..ends.len())
        .filter(|&i| ends[i].kind == Kind::Aperiodic)
        .collect();
    if which.is_empty() {
        return;
    }
    let comps = d.min(3);
    // An orbit's finite samples: a non-finite one lies in no cell.
    let samples = |i: usize| {
        ends[i]
            .points
            .chunks(d)
            .filter(|x| x.iter().all(|v| v.is_finite()))
    };
    let (mut lo, mut hi) = (vec![f64::INFINITY; comps], vec![f64::NEG_INFINITY; comps]);
    for x in which.iter().flat_map(|&i| samples(i)) {
        for k in 0..comps {
            let v = r.coordinate(x, k);
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    for k in 0..comps {
        if let Some(p) = r.wrap[k] {
            (lo[k], hi[k]) = (0.0, p);
        }
    }
    let index = |x: &[f64]| -> usize {
        let mut at = 0;
        for k in 0..comps {
            let width = (hi[k] - lo[k]).max(f64::MIN_POSITIVE);
            let c = ((r.coordinate(x, k) - lo[k]) / width * APERIODIC_CELLS as f64) as usize;
            at = at * APERIODIC_CELLS + c.min(APERIODIC_CELLS - 1);
        }
        at
    };
    let mut parent: Vec<usize> = (0..which.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut owner: HashMap<usize, usize> = HashMap::new();
    for (j, &i) in which.iter().enumerate() {
        for x in samples(i) {
            let o = *owner.entry(index(x)).or_insert(j);
            let (a, b) = (root(&mut parent, o), root(&mut parent, j));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut group_of_root: HashMap<usize, usize> = HashMap::new();
    for (j, &i) in which.iter().enumerate() {
        let rt = root(&mut parent, j);
        let g = *group_of_root.entry(rt).or_insert_with(|| {
            groups.push((Kind::Aperiodic, 0, which[rt]));
            groups.len() - 1
        });
        group[i] = g;
    }
}

/// Attractors continued along a parameter axis: each slice of the ensemble
/// (one value of the parameter, its orbits' indices) labelled on its own,
/// then matched with the slice before it, nearest point sets first among
/// attractors of the same kind and period, so that a label names the same
/// attractor along the axis. `present[label]` is the slices it was found
/// in; labels go by basin size over the whole axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Continued {
    pub labelling: Labelling,
    /// Per label (in `labelling.attractors`' order, escape aside): the
    /// orbits on it in each slice.
    pub counts: Vec<Vec<usize>>,
}

pub fn continue_along(ends: &[End], slices: &[Vec<usize>], r: &Recurrence) -> Continued {
    // Attractors continued so far: (kind, period, points of the latest slice, counts per slice).
    let mut tracks: Vec<(Kind, usize, Vec<f64>, Vec<usize>)> = vec![];
    let mut track_of_orbit = vec![usize::MAX; ends.len()];
    let mut last: Vec<usize> = vec![]; // the tracks found in the previous slice
    for (s, orbits) in slices.iter().enumerate() {
        let local_ends: Vec<End> = orbits.iter().map(|&i| ends[i].clone()).collect();
        let local = label(&local_ends, r);
        let found: Vec<&Attractor> = local.attractors.iter().filter(|a| a.label >= 0).collect();
        // Every (new, previous) pair of one kind and period, nearest first.
        let mut pairs = vec![];
        for (a, new) in found.iter().enumerate() {
            for &t in &last {
                let (kind, period, points, _) = &tracks[t];
                if *kind == new.kind && *period == new.period {
                    pairs.push((hausdorff(&new.points, points, r), a, t));
                }
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        let mut track_of = vec![usize::MAX; found.len()];
        let mut taken = vec![false; tracks.len()];
        for (_, a, t) in pairs {
            if track_of[a] == usize::MAX && !taken[t] {
                track_of[a] = t;
                taken[t] = true;
            }
        }
        for (a, new) in found.iter().enumerate() {
            if track_of[a] == usize::MAX {
                tracks.push((new.kind, new.period, vec![], vec![0; slices.len()]));
                track_of[a] = tracks.len() - 1;
            }
            let t = &mut tracks[track_of[a]];
            t.2 = new.points.clone();
            t.3[s] = new.count;
        }
        for (j, &i) in orbits.iter().enumerate() {
            let l = local.labels[j];
            if l >= 0 {
                track_of_orbit[i] = track_of[l as usize];
            }
        }
        last = track_of.clone();
    }
    // Labels by basin size over the whole axis; ties by first appearance.
    let total = |t: usize| tracks[t].3.iter().sum::<usize>();
    let mut order: Vec<usize> = (0..tracks.len()).collect();
    order.sort_by_key(|&t| (std::cmp::Reverse(total(t)), t));
    let mut label_of = vec![0i32; tracks.len()];
    let mut attractors = vec![];
    let mut counts = vec![];
    for (label, &t) in order.iter().enumerate() {
        label_of[t] = label as i32;
        let (kind, period, points, per_slice) = &tracks[t];
        attractors.push(Attractor {
            label: label as i32,
            kind: *kind,
            period: *period,
            points: points.clone(),
            count: total(t),
        });
        counts.push(per_slice.clone());
    }
    Continued {
        labelling: labelled(&track_of_orbit, &label_of, attractors),
        counts,
    }
}

/// A basin's fraction of `n` orbits and its standard error (binomial: the
/// orbits as a random sample of the initial conditions).
pub fn fraction(count: usize, n: usize) -> (f64, f64) {
    if n == 0 {
        return (0.0, 0.0);
    }
    let f = count as f64 / n as f64;
    (f, (f * (1.0 - f) / n as f64).sqrt())
}

/// The basin entropy S_b and the boundary basin entropy S_bb of a grid of
/// labels (`nx` × `ny`, row-major), in boxes of `side` × `side` cells
/// (Daza, Wagemakers, Georgeot, Guéry-Odelin, Sanjuán 2016): the mean over
/// boxes of −Σ p ln p, p each label's share of the box, and the same mean
/// over the boxes holding more than one label (0 if none does). S_bb > ln 2
/// is their sufficient condition for a fractal boundary.
pub fn basin_entropy(labels: &[i32], nx: usize, ny: usize, side: usize) -> (f64, f64) {
    let side = side.max(1);
    let (bx, by) = (nx / side, ny / side);
    let (mut total, mut boundary, mut boxes, mut boundary_boxes) = (0.0, 0.0, 0usize, 0usize);
    for i in 0..bx {
        for j in 0..by {
            let mut counts: HashMap<i32, usize> = HashMap::new();
            for x in i * side..(i + 1) * side {
                for y in j * side..(j + 1) * side {
                    *counts.entry(labels[x * ny + y]).or_default() += 1;
                }
            }
            let cells = (side * side) as f64;
            let s: f64 = counts
                .values()
                .map(|&c| c as f64 / cells)
                .map(|p| -p * p.ln())
                .sum();
            total += s;
            boxes += 1;
            if counts.len() > 1 {
                boundary += s;
                boundary_boxes += 1;
            }
        }
    }
    let mean = |s: f64, n: usize| if n == 0 { 0.0 } else { s / n as f64 };
    (mean(total, boxes), mean(boundary, boundary_boxes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane() -> Recurrence {
        Recurrence {
            max_period: 8,
            tolerance: 1e-3,
            wrap: vec![None, None],
        }
    }

    fn fixed(x: f64, y: f64) -> End {
        End {
            kind: Kind::FixedPoint,
            period: 1,
            points: vec![x, y],
        }
    }

    fn cycle(points: &[[f64; 2]], shift: usize) -> End {
        let k = points.len();
        End {
            kind: Kind::Periodic,
            period: k,
            points: (0..k).flat_map(|m| points[(m + shift) % k]).collect(),
        }
    }

    #[test]
    fn orbits_on_one_cycle_share_a_label_whatever_their_phase() {
        let c = [[0.0, 1.0], [1.0, 0.0], [0.5, 0.5]];
        let ends = vec![
            cycle(&c, 0),
            fixed(2.0, 2.0),
            cycle(&c, 1),
            cycle(&c, 2),
            fixed(2.0 + 4e-4, 2.0),
            fixed(-3.0, 0.0),
        ];
        let l = label(&ends, &plane());
        // Largest basin first: the cycle (3), the fixed point at (2, 2) (2), (−3, 0) (1).
        assert_eq!(l.labels, vec![0, 1, 0, 0, 1, 2]);
        let kinds: Vec<_> = l
            .attractors
            .iter()
            .map(|a| (a.kind, a.period, a.count))
            .collect();
        assert_eq!(
            kinds,
            vec![
                (Kind::Periodic, 3, 3),
                (Kind::FixedPoint, 1, 2),
                (Kind::FixedPoint, 1, 1)
            ]
        );
    }

    #[test]
    fn points_farther_than_twice_the_tolerance_are_two_attractors_and_escapes_are_minus_one() {
        let escape = End {
            kind: Kind::Escape,
            period: 0,
            points: vec![],
        };
        let ends = vec![fixed(0.0, 0.0), fixed(2.5e-3, 0.0), escape.clone(), escape];
        let l = label(&ends, &plane());
        assert_eq!(l.labels, vec![0, 1, -1, -1]);
        let last = l.attractors.last().unwrap();
        assert_eq!((last.label, last.kind, last.count), (-1, Kind::Escape, 2));
    }

    #[test]
    fn angles_meet_across_their_period() {
        let r = Recurrence {
            max_period: 4,
            tolerance: 1e-3,
            wrap: vec![Some(2.0 * std::f64::consts::PI), None],
        };
        let tau = 2.0 * std::f64::consts::PI;
        let ends = vec![
            fixed(1e-4, 1.0),
            fixed(tau - 1e-4, 1.0),
            fixed(3.0 * tau + 2e-4, 1.0),
        ];
        assert_eq!(label(&ends, &r).labels, vec![0, 0, 0]);
    }

    #[test]
    fn aperiodic_orbits_in_two_regions_are_two_attractors() {
        let cloud = |cx: f64, seed: u64| {
            let mut s = seed;
            let mut next = move || {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64
            };
            End {
                kind: Kind::Aperiodic,
                period: 0,
                points: (0..9).flat_map(|_| [cx + next(), next()]).collect(),
            }
        };
        let ends: Vec<End> = (0..200)
            .map(|i| cloud(if i % 3 == 0 { 10.0 } else { 0.0 }, i))
            .collect();
        let l = label(&ends, &plane());
        let on = |label: i32| l.labels.iter().filter(|x| **x == label).count();
        assert_eq!((on(0), on(1), l.attractors.len()), (133, 67, 2));
        assert!(ends
            .iter()
            .zip(&l.labels)
            .all(|(e, &x)| (e.points[0] >= 10.0) == (x == 1)));
    }

    #[test]
    fn an_attractor_that_moves_along_the_axis_keeps_its_label() {
        // Slice s: a fixed point at (s/10, 0) in every slice, and from slice 2
        // on a second one at (5, s/10); the first gets most orbits.
        let mut ends = vec![];
        let mut slices = vec![];
        for s in 0..5 {
            let mut orbits = vec![];
            for k in 0..6 {
                orbits.push(ends.len());
                let x = s as f64 / 10.0;
                ends.push(if s >= 2 && k < 2 {
                    fixed(5.0, x)
                } else {
                    fixed(x, 0.0)
                });
            }
            slices.push(orbits);
        }
        let c = continue_along(&ends, &slices, &plane());
        assert_eq!(c.labelling.attractors.len(), 2);
        assert_eq!(c.counts, vec![vec![6, 6, 4, 4, 4], vec![0, 0, 2, 2, 2]]);
        for (e, &l) in ends.iter().zip(&c.labelling.labels) {
            assert_eq!(l, i32::from(e.points[0] == 5.0));
        }
        // Labelled as one ensemble instead, each slice's point is its own attractor.
        assert_eq!(label(&ends, &plane()).attractors.len(), 8);
    }

    #[test]
    fn fractions_have_binomial_errors() {
        let (f, e) = fraction(250, 1000);
        assert_eq!(f, 0.25);
        assert!((e - (0.25f64 * 0.75 / 1000.0).sqrt()).abs() < 1e-15);
        assert_eq!(fraction(0, 0), (0.0, 0.0));
    }

    #[test]
    fn basin_entropy_of_known_grids() {
        // One basin: no entropy, no boundary.
        assert_eq!(basin_entropy(&[0; 100], 10, 10, 5), (0.0, 0.0));
        // A checkerboard of two basins: every box half and half.
        let board: Vec<i32> = (0..100).map(|k| (k / 10 + k % 10) % 2).collect();
        let (sb, sbb) = basin_entropy(&board, 10, 10, 2);
        let ln2 = std::f64::consts::LN_2;
        assert!((sb - ln2).abs() < 1e-15 && (sbb - ln2).abs() < 1e-15);
        // Two half-planes split at x = 5 with boxes of 2: 5 box columns, the
        // middle one (x = 4, 5) on the boundary, half and half.
        let halves: Vec<i32> = (0..100).map(|k| i32::from(k / 10 >= 5)).collect();
        let (sb, sbb) = basin_entropy(&halves, 10, 10, 2);
        assert!((sb - ln2 / 5.0).abs() < 1e-15, "{sb}");
        assert!((sbb - ln2).abs() < 1e-15);
    }
}
