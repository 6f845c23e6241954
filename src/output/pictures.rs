//! Quick-look pictures of a run, so a person understands it at a glance:
//! heat maps (or curves) of every statistic over the scene's axes, a phase
//! portrait of the trajectories, a Poincaré portrait of the sections, and a
//! map of where trajectories stopped.

use std::f64::consts::{PI, SQRT_2};
use std::path::Path;

use anyhow::Result;

use crate::num::order::ascending;
use crate::num::precision::Real;
use crate::output::doubts::Doubts;
use crate::output::plot::{self, fmt_significant, Figure, HeatMap, Rgb, Series};
use crate::plan::observations::Observations;
use crate::plan::observers::ResonanceObs;
use crate::scene::Scene;

fn f64s<R: Real>(v: &[R]) -> Vec<f64> {
    v.iter().map(|x| x.to_f64()).collect()
}

/// A statistic along one axis as a picture draws it: at most ~2·10⁵
/// points (a longer curve is reduced to the minimum and maximum of each
/// bin, its envelope, which is all a picture shows), and what its gaps mean
/// (each kind once, in the order met along the axis). One pass over the
/// values, the bins on every core.
struct Curve {
    x: Vec<f64>,
    y: Vec<f64>,
    gaps: Vec<&'static str>,
}

impl Curve {
    fn new(x: &[f64], at: impl Fn(usize) -> Result<f64, Undefined> + Sync) -> Curve {
        use rayon::prelude::*;
        const BINS: usize = 100_000;
        let n = x.len();
        let whole = n <= 2 * BINS;
        let bins = if whole { n } else { BINS };
        let parts: Vec<Bin> = (0..bins)
            .into_par_iter()
            .map(|b| Bin::of(x, &at, b * n / bins..(b + 1) * n / bins, whole))
            .collect();
        let mut curve = Curve {
            x: Vec::with_capacity(2 * bins),
            y: Vec::with_capacity(2 * bins),
            gaps: vec![],
        };
        for bin in &parts {
            let points = &bin.points[..bin.len];
            curve.x.extend(points.iter().map(|p| p.0));
            curve.y.extend(points.iter().map(|p| p.1));
            for g in &bin.gaps[..bin.kinds] {
                let g = gap_name(*g);
                if !curve.gaps.contains(&g) {
                    curve.gaps.push(g);
                }
            }
        }
        curve
    }

    /// `label`, saying what the curve's gaps mean where it has any.
    fn label(&self, label: &str) -> String {
        if self.gaps.is_empty() {
            label.to_string()
        } else {
            format!("{label} (gaps: {})", self.gaps.join(", "))
        }
    }
}

/// One bin of a [`Curve`]: its points (the value itself, or the minimum
/// and maximum in the order met) and the kinds of its gaps in the order met
/// (an index into [`UNDEFINED`], or [`NAN_GAP`]).
struct Bin {
    points: [(f64, f64); 2],
    len: usize,
    gaps: [u8; UNDEFINED.len() + 1],
    kinds: usize,
}

/// A gap kind of a finite-looking value that is not finite.
const NAN_GAP: u8 = u8::MAX;

fn gap_name(kind: u8) -> &'static str {
    match kind {
        NAN_GAP => "NaN",
        u => UNDEFINED[u as usize].0,
    }
}

impl Bin {
    /// The bin of trajectories `range` (one value when `whole`).
    fn of(
        x: &[f64],
        at: &impl Fn(usize) -> Result<f64, Undefined>,
        range: std::ops::Range<usize>,
        whole: bool,
    ) -> Bin {
        let lo = range.start;
        let mut bin = Bin {
            points: [(0.0, 0.0); 2],
            len: 0,
            gaps: [0; UNDEFINED.len() + 1],
            kinds: 0,
        };
        let (mut mn, mut mx) = ((f64::INFINITY, lo), (f64::NEG_INFINITY, lo));
        for i in range {
            let value = at(i);
            let gap = match value {
                Err(u) => Some(u as u8),
                Ok(v) if !v.is_finite() => Some(NAN_GAP),
                Ok(_) => None,
            };
            if let Some(g) = gap.filter(|g| !bin.gaps[..bin.kinds].contains(g)) {
                bin.gaps[bin.kinds] = g;
                bin.kinds += 1;
            }
            let v = or_nan(value);
            if whole {
                (bin.points[0], bin.len) = ((x[i], v), 1);
                return bin;
            }
            if v < mn.0 {
                mn = (v, i);
            }
            if v > mx.0 {
                mx = (v, i);
            }
        }
        let (a, b) = if mn.1 <= mx.1 { (mn, mx) } else { (mx, mn) };
        let finite = |v: f64| if v.is_finite() { v } else { f64::NAN };
        bin.points = [(x[a.1], finite(a.0)), (x[b.1], finite(b.0))];
        bin.len = 2;
        bin
    }
}

/// Draws the pictures into `dir`; returns the file names written.
pub fn draw<R: Real>(
    scene: &Scene,
    dir: &Path,
    d: &Observations<R>,
    doubts: &Doubts,
) -> Result<Vec<String>> {
    let title = scene
        .title
        .clone()
        .unwrap_or_else(|| format!("{} ({}, {})", scene.name, scene.model.name(), scene.scheme));
    let pictures = Pictures::new(scene, dir, &title, (R::NAME, R::UNIT_ROUNDOFF));
    let stats = statistics(d, doubts);
    // The first two axes with more than one value span the maps; the others
    // are held at their first value.
    let mut files = match pictures.varying[..] {
        [] => vec![],
        [k] => pictures.stat_curves(&stats, k)?,
        [kx, ky, ..] => pictures.stat_maps(&stats, kx, ky)?,
    };
    files.extend(pictures.phase_portrait(d)?);
    files.extend(pictures.poincare_portrait(d)?);
    files.extend(pictures.poincare_by_fli(d)?);
    files.extend(pictures.running_indicators(d)?);
    files.extend(pictures.bifurcation_diagram(d)?);
    if let Some(r) = &scene.observers.resonance {
        let index = crate::output::arrays::resonance(r, d)?;
        files.extend(pictures.resonance_map(r, &index)?);
        files.push(pictures.capture_fractions(r, &index)?);
    }
    Ok(files)
}

/// Why a trajectory has no value of a statistic: the grey of its cell in
/// a heat map (`UNDEFINED[why as usize]`), never a colour of the scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Undefined {
    /// The trajectory stopped on a non-finite state.
    NonFinite,
    /// Fewer than two upward crossings of the cycle level in the window:
    /// neither a period nor an amplitude of a cycle.
    NoCycle,
    /// `status_step` of a trajectory that never stopped.
    RanToEnd,
    /// A chaos indicator of a trajectory the stop condition ended: it
    /// measures only the time before.
    Stopped,
    /// A chaos indicator lost: the deviation vectors left the precision's
    /// range between two samples.
    Lost,
    /// A Lyapunov exponent the spacing of the re-orthonormalisations does
    /// not resolve (`doubts.rs`).
    Unresolved,
}

/// What each `Undefined` means, and its grey.
const UNDEFINED: [(&str, Rgb); 6] = [
    ("non-finite (stopped)", (100, 100, 100)),
    ("no cycle found", (200, 200, 200)),
    ("ran to the end", (200, 200, 200)),
    ("stopped (output.stop)", (150, 150, 150)),
    ("vectors overflowed", (175, 175, 175)),
    ("not resolved (every too large)", (230, 230, 230)),
];

/// A statistic's value for trajectory `i`, or why it has none.
type Value<'a> = Box<dyn Fn(usize) -> Result<f64, Undefined> + Sync + 'a>;

/// A statistic of the run: file stem, label, and its value for trajectory
/// `i`. Accessors on the run's arrays: the pictures read only the slice
/// they draw, never a copy of a whole (possibly 10⁷-long) array.
type Stat<'a> = (String, String, Value<'a>);

/// The statistics drawn over the axes: every final value, the cycle's
/// amplitude and period if observed, the time averages, and where
/// trajectories stopped (non-finite, or by the stop condition) if any did.
/// A trajectory that became non-finite has no final value and no cycle; one
/// whose cycle variable did not cross its level twice has no cycle (its
/// amplitude array still holds the half-range of a transient or a rest).
fn statistics<'a, R: Real>(d: &'a Observations<R>, doubts: &'a Doubts) -> Vec<Stat<'a>> {
    let stopped = move |i: usize| d.nonfinite_step[i] != 0;
    let ended = move |i: usize| d.nonfinite_step[i].max(d.stop_step[i]);
    let mut stats: Vec<Stat> = vec![];
    stats.extend(per_variable(d, "final", &d.final_values));
    if !d.cycle_amplitude.is_empty() {
        let cycle = move |i: usize, v: &[R]| {
            if stopped(i) {
                Err(Undefined::NonFinite)
            } else if !d.cycle_period[i].to_f64().is_finite() {
                Err(Undefined::NoCycle)
            } else {
                Ok(v[i].to_f64())
            }
        };
        let amplitude = move |i| cycle(i, &d.cycle_amplitude);
        let period = move |i| cycle(i, &d.cycle_period);
        stats.push((
            "cycle_amplitude".into(),
            "cycle amplitude".into(),
            Box::new(amplitude),
        ));
        stats.push((
            "cycle_period".into(),
            "cycle period".into(),
            Box::new(period),
        ));
    }
    stats.extend(per_variable(d, "mean", &d.mean));
    stats.extend(indicators(d, doubts));
    if (0..d.n).any(|i| ended(i) != 0) {
        let step = move |i| match ended(i) {
            0 => Err(Undefined::RanToEnd),
            step => Ok(f64::from(step)),
        };
        stats.push((
            "status_step".into(),
            "step at which it stopped".into(),
            Box::new(step),
        ));
    }
    stats
}

/// The chaos indicators: each Lyapunov exponent (`lyapunov_1` the
/// largest), the FLI, MEGNO, and SALI and GALI as their decimal
/// logarithms (which read as the exponential decay on chaotic orbits),
/// those below the precision's ε at ε; none for a trajectory that became
/// non-finite, one the stop condition ended, one whose vectors overflowed,
/// nor an exponent the samples do not resolve.
fn indicators<'a, R: Real>(d: &'a Observations<R>, doubts: &'a Doubts) -> Vec<Stat<'a>> {
    let value = move |i: usize, x: R| match (d.nonfinite_step[i], d.stop_step[i]) {
        (0, 0) if x.finite() => Ok(x.to_f64()),
        (0, 0) => Err(Undefined::Lost),
        (0, _) => Err(Undefined::Stopped),
        _ => Err(Undefined::NonFinite),
    };
    let k = d.exponents;
    let exponent = move |i: usize, j: usize| match doubts.resolved(i, j, k) {
        true => value(i, d.lyapunov[i * k + j]),
        false => Err(Undefined::Unresolved),
    };
    let mut stats: Vec<Stat> = (0..k)
        .map(|j| -> Stat {
            (
                format!("lyapunov_{}", j + 1),
                format!("Lyapunov exponent λ{}", j + 1),
                Box::new(move |i| exponent(i, j)),
            )
        })
        .collect();
    let floor = alignment_floor(R::UNIT_ROUNDOFF);
    for (look, v) in LOOKS.iter().zip(d.scalar_indicators(false)) {
        if v.is_empty() {
            continue;
        }
        let at = move |i: usize| value(i, v[i]);
        let stat: Value = match look.log {
            true => Box::new(move |i| at(i).map(|x| x.max(floor).log10())),
            false => Box::new(at),
        };
        stats.push((look.file.into(), look.label.into(), stat));
    }
    stats
}

/// How one of `indicators::SCALAR_INDICATORS` is drawn.
struct Look {
    /// Its map's file and label.
    file: &'static str,
    label: &'static str,
    /// Drawn as its decimal logarithm, values below the precision's ε at ε.
    log: bool,
    /// The map's colour range, for the scene and the precision's unit
    /// round-off.
    range: fn(&Scene, f64) -> (f64, f64),
    /// Its running values' label, and whether their axes (step, value) are
    /// logarithmic.
    running: &'static str,
    log_axes: (bool, bool),
}

/// The looks of `indicators::SCALAR_INDICATORS`, in its order. SALI falls
/// exponentially on chaotic orbits (a line against the step on a log
/// scale), GALI also as powers of t on regular ones (lines on log–log
/// axes).
const LOOKS: [Look; 4] = [
    Look {
        file: "fli",
        label: "FLI",
        log: false,
        range: |scene, _| fli_range(scene),
        running: "FLI so far",
        log_axes: (false, false),
    },
    Look {
        file: "megno",
        label: "MEGNO ⟨Y⟩",
        log: false,
        range: |_, _| MEGNO_RANGE,
        running: "MEGNO ⟨Y⟩ so far",
        log_axes: (false, false),
    },
    Look {
        file: "sali",
        label: "log₁₀ SALI",
        log: true,
        range: |_, u| (alignment_floor(u).log10(), SQRT_2.log10()),
        running: "SALI",
        log_axes: (false, true),
    },
    Look {
        file: "gali",
        label: "log₁₀ GALI",
        log: true,
        range: |_, u| (alignment_floor(u).log10(), 0.0),
        running: "GALI",
        log_axes: (true, true),
    },
];

/// The smallest SALI or GALI the maps tell apart: the precision's ε (twice
/// its unit round-off `u`), where the unit vectors' differences are
/// round-off.
fn alignment_floor(u: f64) -> f64 {
    2.0 * u
}

/// The class of each cell of the grid over the first two axes with more
/// than one value (the others at their first value): `class(row)` of the
/// cell's trajectory, as `(kx, ky, classes[ix · len(ky) + iy])`; `None`
/// with fewer than two such axes. What a categorical map shows.
pub fn classes_over_first_two(
    scene: &Scene,
    class: impl Fn(usize) -> u8,
) -> Option<(usize, usize, Vec<u8>)> {
    let (shape, strides) = (scene.shape(), scene.strides());
    let varying: Vec<usize> = (0..shape.len()).filter(|&k| shape[k] > 1).collect();
    let [kx, ky, ..] = varying[..] else {
        return None;
    };
    let mut classes = vec![0u8; shape[kx] * shape[ky]];
    for ix in 0..shape[kx] {
        for iy in 0..shape[ky] {
            classes[ix * shape[ky] + iy] = class(ix * strides[kx] + iy * strides[ky]);
        }
    }
    Some((kx, ky, classes))
}

/// The colour of resonance class `k` in both pictures: the palette's, grey
/// for `none` (the index past the ratios).
fn class_colour(k: usize, none: usize) -> plot::Rgb {
    if k == none {
        (200, 200, 200)
    } else {
        plot::palette(k)
    }
}

/// The per cent of the trajectories each ratio captured, then none.
fn percents(r: &ResonanceObs, index: &[i32]) -> Vec<f64> {
    let n = index.len().max(1) as f64;
    r.counts(index)
        .iter()
        .map(|c| 100.0 * *c as f64 / n)
        .collect()
}

/// `<prefix>_<var>` of each variable of `arrays` (final values, means):
/// none for a trajectory that became non-finite.
fn per_variable<'a, R: Real>(
    d: &'a Observations<R>,
    prefix: &'a str,
    arrays: &'a [(String, Vec<R>)],
) -> impl Iterator<Item = Stat<'a>> + 'a {
    arrays.iter().map(move |(name, v)| -> Stat<'a> {
        let value = move |i: usize| {
            if d.nonfinite_step[i] != 0 {
                Err(Undefined::NonFinite)
            } else {
                Ok(v[i].to_f64())
            }
        };
        (
            format!("{prefix}_{name}"),
            format!("{prefix} {name}"),
            Box::new(value),
        )
    })
}

/// A statistic's value as drawn: NaN where it has none.
fn or_nan(v: Result<f64, Undefined>) -> f64 {
    v.unwrap_or(f64::NAN)
}

/// What every picture of a run needs: the scene, where its trajectories
/// sit on its axes, the directory and the title.
struct Pictures<'a> {
    scene: &'a Scene,
    dir: &'a Path,
    title: &'a str,
    shape: Vec<usize>,
    /// Trajectories.
    n: usize,
    /// The axes with more than one value.
    varying: Vec<usize>,
    strides: Vec<usize>,
    /// The run's precision and its unit round-off.
    precision: (&'static str, f64),
    /// Per axis, the significant digits that tell its values apart (found
    /// when a label first needs them: a long axis takes a while).
    digits: Vec<std::sync::OnceLock<usize>>,
}

impl<'a> Pictures<'a> {
    fn new(
        scene: &'a Scene,
        dir: &'a Path,
        title: &'a str,
        precision: (&'static str, f64),
    ) -> Self {
        let shape = scene.shape();
        let n: usize = shape.iter().product();
        let varying: Vec<usize> = (0..shape.len()).filter(|k| shape[*k] > 1).collect();
        Self {
            scene,
            dir,
            title,
            shape,
            n,
            varying,
            strides: scene.strides(),
            precision,
            digits: scene.axes.iter().map(|_| Default::default()).collect(),
        }
    }

    fn figure<'f>(&'f self, x_label: &'f str, y_label: &'f str) -> Figure<'f> {
        Figure {
            title: self.title,
            x_label,
            y_label,
            ..Figure::default()
        }
    }

    /// One axis varies: each statistic as a curve over it.
    fn stat_curves(&self, stats: &[Stat], k: usize) -> Result<Vec<String>> {
        use rayon::prelude::*;
        let ax = &self.scene.axes[k];
        let x_log = plot::log_scale(&ax.values);
        // Each picture is drawn by one thread: the statistics side by side.
        let each = |(file, label, v): &Stat| -> Result<String> {
            let curve = Curve::new(&ax.values, |i| v(i * self.strides[k]));
            let (x, y) = (&curve.x, &curve.y);
            let label = &curve.label(label);
            let label = &round_off_label(label, y, self.precision);
            let name = format!("{file}.png");
            plot::lines(
                &self.dir.join(&name),
                &self.figure(&ax.name, label),
                &[Series::new(label, x, y)],
                x_log,
                false,
            )?;
            Ok(name)
        };
        stats.par_iter().map(each).collect()
    }

    /// Two or more axes vary: each statistic as a heat map over the first two.
    fn stat_maps(&self, stats: &[Stat], kx: usize, ky: usize) -> Result<Vec<String>> {
        let (shape, strides) = (&self.shape, &self.strides);
        let (ax, ay) = (&self.scene.axes[kx], &self.scene.axes[ky]);
        // The resonances' values p/q, marked on the colour bar of their mean.
        let resonant: Vec<(f64, String)> = self
            .scene
            .observers
            .resonance
            .iter()
            .flat_map(|r| {
                r.ratios
                    .iter()
                    .enumerate()
                    .map(|(k, [p, q])| (*p as f64 / *q as f64, r.label(k)))
            })
            .collect();
        let marks_of = |file: &str| -> Vec<(f64, &str)> {
            match &self.scene.observers.resonance {
                Some(r) if file == format!("mean_{}", r.var) => {
                    resonant.iter().map(|(v, l)| (*v, l.as_str())).collect()
                }
                _ => vec![],
            }
        };
        use rayon::prelude::*;
        let (x_log, y_log) = (plot::log_scale(&ax.values), plot::log_scale(&ay.values));
        // Each picture is drawn by one thread: the statistics side by side.
        let each = |(file, label, v): &Stat| -> Result<String> {
            let mut grid = vec![f64::NAN; shape[kx] * shape[ky]];
            let mut why = vec![u8::MAX; grid.len()];
            for ix in 0..shape[kx] {
                for iy in 0..shape[ky] {
                    let k = ix * shape[ky] + iy;
                    match v(ix * strides[kx] + iy * strides[ky]) {
                        Ok(x) => grid[k] = x,
                        Err(u) => why[k] = u as u8,
                    }
                }
            }
            let label = &round_off_label(label, &grid, self.precision);
            let label = &match LOOKS.iter().find(|l| l.file == file) {
                Some(l) => clip_to(&mut grid, label, (l.range)(self.scene, self.precision.1)),
                None => clip_outliers(&mut grid, label),
            };
            let name = format!("{file}.png");
            let map = HeatMap {
                x: &ax.values,
                y: &ay.values,
                values: &grid,
                label,
                log_color: log_colour(&grid),
                x_log,
                y_log,
                why: &why,
                undefined: &UNDEFINED,
                marks: &marks_of(file),
            };
            plot::heat_map(
                &self.dir.join(&name),
                &self.figure(&ax.name, &ay.name),
                &map,
            )?;
            Ok(name)
        };
        stats.par_iter().map(each).collect()
    }

    /// Phase portrait of (at most `plot.max_trajectories`, evenly chosen)
    /// trajectories: `trajectory.png`, if the run recorded trajectories.
    fn phase_portrait<R: Real>(&self, d: &Observations<R>) -> Result<Option<String>> {
        if d.frames <= 1 || d.trajectory.is_empty() {
            return Ok(None);
        }
        let names: Vec<&str> = d.trajectory.iter().map(|(v, _)| v.as_str()).collect();
        let Some((jx, jy)) = phase_pair(self.scene, &names) else {
            return Ok(None);
        };
        let n = self.n;
        let count = self.scene.plot.max_trajectories.max(1).min(n);
        let chosen: Vec<usize> = (0..count).map(|c| c * n / count).collect();
        let of = |j: usize, i: usize| f64s(&d.trajectory[j].1[i * d.frames..(i + 1) * d.frames]);
        let xs: Vec<Vec<f64>> = chosen.iter().map(|i| of(jx, *i)).collect();
        let mut ys: Vec<Vec<f64>> = chosen.iter().map(|i| of(jy, *i)).collect();
        let mut y_label = names[jy].to_string();
        if self.scene.plot.lienard_plane {
            self.lienard_plane(&chosen, &xs, &mut ys);
            y_label = "q − q³/3 − s/ε".into();
        }
        // Few trajectories: a colour and a legend entry each. More than the
        // palette has: a colour per band of the last varying axis, so
        // that no two bands share a colour and the legend names each.
        let bands = Bands::of(chosen.len(), &self.varying, &self.shape);
        let (labels, colours): (Vec<String>, Vec<Option<Rgb>>) = if bands.per_orbit {
            let label = |i: &usize| self.trajectory_label(*i);
            (chosen.iter().map(label).collect(), vec![None; chosen.len()])
        } else {
            let band = |i: &usize| bands.of_orbit(*i, &self.shape, &self.strides);
            let label = |b: usize| bands.label(b, self);
            let b: Vec<usize> = chosen.iter().map(band).collect();
            let colour = |b: &usize| Some(plot::palette(*b));
            (
                b.iter().map(|b| label(*b)).collect(),
                b.iter().map(colour).collect(),
            )
        };
        let series: Vec<Series> = (0..chosen.len())
            .map(|c| Series {
                color: colours[c],
                ..Series::new(&labels[c], &xs[c], &ys[c])
            })
            .collect();
        let fig = self.figure(names[jx], &y_label);
        plot::lines(
            &self.dir.join("trajectory.png"),
            &fig,
            &series,
            false,
            false,
        )?;
        Ok(Some("trajectory.png".into()))
    }

    /// Liénard plane: y = q − q³/3 − s/ε, ε of each trajectory.
    fn lienard_plane(&self, chosen: &[usize], qs: &[Vec<f64>], ys: &mut [Vec<f64>]) {
        for (c, i) in chosen.iter().enumerate() {
            let eps = self.scene.param_value("epsilon", *i, &self.strides);
            for (y, q) in ys[c].iter_mut().zip(&qs[c]) {
                *y = q - q * q * q / 3.0 - *y / eps;
            }
        }
    }

    /// Poincaré portrait of every orbit's section points: `poincare.png`,
    /// if the run recorded sections.
    fn poincare_portrait<R: Real>(&self, d: &Observations<R>) -> Result<Option<String>> {
        if d.max_points == 0 || d.poincare.len() < 2 {
            return Ok(None);
        }
        let names: Vec<&str> = d.poincare.iter().map(|(v, _)| v.as_str()).collect();
        let (jx, jy) = poincare_pair(self.scene, &names);
        let wrap_x = self.scene.plot.wrap_x.as_deref();
        let bands = Bands::of(self.n, &self.varying, &self.shape);
        let mut xs: Vec<Vec<f64>> = vec![vec![]; bands.count];
        let mut ys: Vec<Vec<f64>> = vec![vec![]; bands.count];
        self.section_points(d, (jx, jy), |i, x, y| {
            let b = bands.of_orbit(i, &self.shape, &self.strides);
            xs[b].push(x);
            ys[b].push(y);
        });
        let labels: Vec<String> = (0..xs.len()).map(|b| bands.label(b, self)).collect();
        let series: Vec<Series> = (0..xs.len())
            .map(|c| Series::new(&labels[c], &xs[c], &ys[c]))
            .collect();
        let fig = self.figure(names[jx], names[jy]);
        plot::point_cloud(
            &self.dir.join("poincare.png"),
            &fig,
            &series,
            x_range(wrap_x),
            None,
        )?;
        Ok(Some("poincare.png".into()))
    }

    /// Every kept section point as `point(orbit, x, y)`: variables `jx`
    /// and `jy` of the section, x wrapped as `plot.wrap_x` says.
    fn section_points<R: Real>(
        &self,
        d: &Observations<R>,
        (jx, jy): (usize, usize),
        mut point: impl FnMut(usize, f64, f64),
    ) {
        let wrap_x = self.scene.plot.wrap_x.as_deref();
        for i in 0..self.n {
            let first = i * d.max_points;
            let k = (d.poincare_count[i] as usize).min(d.max_points);
            for p in first..first + k {
                let x = wrap(wrap_x, d.poincare[jx].1[p].to_f64());
                point(i, x, d.poincare[jy].1[p].to_f64());
            }
        }
    }

    /// The Poincaré portrait with each orbit's points coloured by its FLI
    /// (`poincare_fli.png`, on [`fli_range`]), if the run has both.
    fn poincare_by_fli<R: Real>(&self, d: &Observations<R>) -> Result<Option<String>> {
        if d.max_points == 0 || d.poincare.len() < 2 || d.fli.is_empty() {
            return Ok(None);
        }
        let names: Vec<&str> = d.poincare.iter().map(|(v, _)| v.as_str()).collect();
        let (jx, jy) = poincare_pair(self.scene, &names);
        let wrap_x = self.scene.plot.wrap_x.as_deref();
        let (mut x, mut y, mut fli) = (vec![], vec![], vec![]);
        self.section_points(d, (jx, jy), |i, px, py| {
            x.push(px);
            y.push(py);
            fli.push(d.fli[i].to_f64());
        });
        let range = fli_range(self.scene);
        let label = format!(
            "the orbit's FLI (the largest in a pixel; clipped to [{}, {}])",
            fmt_significant(range.0, 3),
            fmt_significant(range.1, 3)
        );
        let by_value = plot::ByValue {
            values: &fli,
            range,
            label: &label,
        };
        let fig = self.figure(names[jx], names[jy]);
        let file = "poincare_fli.png";
        let series = Series::new("", &x, &y);
        plot::valued_cloud(
            &self.dir.join(file),
            &fig,
            &series,
            &by_value,
            x_range(wrap_x),
            None,
        )?;
        Ok(Some(file.into()))
    }

    /// Each indicator's running value against the step for the trajectories
    /// a phase portrait shows (`trajectory_lyapunov_1.png`,
    /// `trajectory_fli.png`, `trajectory_megno.png`), if frames recorded them.
    fn running_indicators<R: Real>(&self, d: &Observations<R>) -> Result<Vec<String>> {
        let (frames, k) = (d.frames, d.exponents);
        if frames <= 1 {
            return Ok(vec![]);
        }
        let every = self
            .scene
            .observers
            .trajectory
            .as_ref()
            .map_or(1, |t| t.every);
        let step: Vec<f64> = (0..frames).map(|f| (f as u64 * every) as f64).collect();
        let count = self.scene.plot.max_trajectories.max(1).min(self.n);
        let chosen: Vec<usize> = (0..count).map(|c| c * self.n / count).collect();
        let labels: Vec<String> = chosen.iter().map(|i| self.trajectory_label(*i)).collect();
        // (file, label, logarithmic axes, value at trajectory and frame)
        type Running<'d> = (
            String,
            &'static str,
            (bool, bool),
            Box<dyn Fn(usize, usize) -> f64 + 'd>,
        );
        let mut running: Vec<Running> = vec![];
        if !d.trajectory_lyapunov.is_empty() && k > 0 {
            running.push((
                "trajectory_lyapunov_1".into(),
                "λ1 so far",
                (false, false),
                Box::new(|i, f| d.trajectory_lyapunov[(i * frames + f) * k].to_f64()),
            ));
        }
        for (look, v) in LOOKS.iter().zip(d.scalar_indicators(true)) {
            if !v.is_empty() {
                running.push((
                    format!("trajectory_{}", look.file),
                    look.running,
                    look.log_axes,
                    Box::new(move |i, f| v[i * frames + f].to_f64()),
                ));
            }
        }
        let mut files = vec![];
        for (file, label, (x_log, y_log), at) in running {
            let ys: Vec<Vec<f64>> = chosen
                .iter()
                .map(|i| (0..frames).map(|f| at(*i, f)).collect())
                .collect();
            let series: Vec<Series> = (0..chosen.len())
                .map(|c| Series::new(&labels[c], &step, &ys[c]))
                .collect();
            let name = format!("{file}.png");
            plot::lines(
                &self.dir.join(&name),
                &self.figure("step", label),
                &series,
                x_log,
                y_log,
            )?;
            files.push(name);
        }
        Ok(files)
    }

    /// Which resonance each trajectory was captured in, over the first two
    /// varying axes (`output.resonance`): `resonance.png`, a colour per
    /// ratio (with the fraction of the ensemble in its legend), grey for
    /// none.
    fn resonance_map(&self, r: &ResonanceObs, index: &[i32]) -> Result<Option<String>> {
        let none = r.ratios.len();
        let class = |row: usize| usize::try_from(index[row]).unwrap_or(none) as u8;
        let Some((kx, ky, classes)) = classes_over_first_two(self.scene, class) else {
            return Ok(None);
        };
        let percent = percents(r, index);
        let labels: Vec<String> = (0..=none)
            .map(|k| format!("{} ({:.1} %)", r.label(k), percent[k]))
            .collect();
        let legend: Vec<(&str, plot::Rgb)> = labels
            .iter()
            .enumerate()
            .map(|(k, l)| (l.as_str(), class_colour(k, none)))
            .collect();
        let (ax, ay) = (&self.scene.axes[kx], &self.scene.axes[ky]);
        let name = "resonance.png".to_string();
        plot::class_map(
            &self.dir.join(&name),
            &self.figure(&ax.name, &ay.name),
            &ax.values,
            &ay.values,
            &classes,
            &legend,
            plot::log_scale(&ax.values),
            plot::log_scale(&ay.values),
        )?;
        Ok(Some(name))
    }

    /// The fraction of the ensemble in each resonance and in none
    /// (`output.resonance`): `capture.png`, a bar chart in per cent.
    fn capture_fractions(&self, r: &ResonanceObs, index: &[i32]) -> Result<String> {
        let none = r.ratios.len();
        let percent = percents(r, index);
        let labels: Vec<String> = (0..=none).map(|k| r.label(k)).collect();
        let bars: Vec<(&str, f64, plot::Rgb)> = labels
            .iter()
            .enumerate()
            .map(|(k, l)| (l.as_str(), percent[k], class_colour(k, none)))
            .collect();
        let y_label = format!("% of the {} trajectories (mean {})", index.len(), r.var);
        let name = "capture.png".to_string();
        plot::bars(
            &self.dir.join(&name),
            &self.figure("resonance p:q", &y_label),
            &bars,
            1,
        )?;
        Ok(name)
    }

    /// Bifurcation diagram: every section value of `var` against its
    /// trajectory's value on `axis` (`plot.bifurcation`): `bifurcation.png`.
    fn bifurcation_diagram<R: Real>(&self, d: &Observations<R>) -> Result<Option<String>> {
        let (Some((axis, var)), true) = (&self.scene.plot.bifurcation, d.max_points > 0) else {
            return Ok(None);
        };
        let k = self.scene.axes.iter().position(|a| &a.name == axis);
        let j = d.poincare.iter().position(|(v, _)| v == var);
        let (Some(k), Some(j)) = (k, j) else {
            return Ok(None);
        };
        let (mut xs, mut ys) = (vec![], vec![]);
        for i in 0..self.n {
            let a = self.scene.axes[k].values[(i / self.strides[k]) % self.shape[k]];
            for p in 0..(d.poincare_count[i] as usize).min(d.max_points) {
                xs.push(a);
                ys.push(d.poincare[j].1[i * d.max_points + p].to_f64());
            }
        }
        plot::point_cloud(
            &self.dir.join("bifurcation.png"),
            &self.figure(axis, var),
            &[Series::new(var, &xs, &ys)],
            None,
            None,
        )?;
        Ok(Some("bifurcation.png".into()))
    }
}

/// Values that differ by no more than round-off (64 units in the last
/// place of the run's precision) are noise, however far a colour scale or
/// a curve's axis stretches them: the label says so.
fn round_off_label(label: &str, values: &[f64], (name, unit): (&str, f64)) -> String {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let spread = hi - lo;
    if spread > 0.0 && spread <= 128.0 * unit * lo.abs().max(hi.abs()) {
        format!("{label} (spread {spread:.1e}: {name} round-off)")
    } else {
        label.to_string()
    }
}

/// Values far outside the bulk (a method blowing up, yet still finite)
/// would flatten the colours of everything else: clips the grid's values to
/// Tukey's fences, the quartiles ± 3 IQR, and says so in the returned label.
fn clip_outliers(grid: &mut [f64], label: &str) -> String {
    let mut label = label.to_string();
    let mut sorted: Vec<f64> = grid.iter().copied().filter(|x| x.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    if sorted.len() >= 8 {
        let (q1, q3) = (sorted[sorted.len() / 4], sorted[3 * sorted.len() / 4]);
        let (lo, hi) = (q1 - 3.0 * (q3 - q1), q3 + 3.0 * (q3 - q1));
        if q3 > q1 && (sorted[0] < lo || sorted[sorted.len() - 1] > hi) {
            for x in grid.iter_mut().filter(|x| x.is_finite()) {
                *x = x.clamp(lo, hi);
            }
            label.push_str(" (colours clipped to quartiles ± 3 IQR)");
        }
    }
    label
}

/// MEGNO's colour range in maps, as the literature draws them: ⟨Y⟩ → 2
/// for quasi-periodic orbits, growing for chaotic ones.
const MEGNO_RANGE: (f64, f64) = (0.0, 8.0);

/// The FLI's colour range in maps and portraits: [0, 2 ln T], T the run's
/// time. A regular orbit's deviation grows linearly (its FLI ends near
/// ln T), a chaotic one's exponentially: FLI maps are read against ln T,
/// and everything well beyond it is chaotic, so the scale saturates there.
fn fli_range(scene: &Scene) -> (f64, f64) {
    (0.0, (2.0 * scene.duration().ln()).max(1.0))
}

/// Clips the grid's values to `range` and says so in the returned label.
fn clip_to(grid: &mut [f64], label: &str, (lo, hi): (f64, f64)) -> String {
    for x in grid.iter_mut().filter(|x| x.is_finite()) {
        *x = x.clamp(lo, hi);
    }
    let (lo, hi) = (fmt_significant(lo, 3), fmt_significant(hi, 3));
    format!("{label} (colours clipped to [{lo}, {hi}])")
}

/// The x range of a portrait whose x is wrapped (`plot.wrap_x`).
fn x_range(wrap_x: Option<&str>) -> Option<(f64, f64)> {
    match wrap_x {
        Some("2pi") => Some((0.0, 2.0 * PI)),
        Some("pi") => Some((-PI, PI)),
        _ => None,
    }
}

/// Colours on a log scale: every finite value positive, spanning more than
/// three decades.
fn log_colour(grid: &[f64]) -> bool {
    let positive = grid.iter().filter(|x| x.is_finite()).all(|x| *x > 0.0);
    let spread = {
        let f: Vec<f64> = grid
            .iter()
            .copied()
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        let (lo, hi) = f
            .iter()
            .fold((f64::INFINITY, 0.0f64), |a, x| (a.0.min(*x), a.1.max(*x)));
        hi / lo
    };
    positive && spread > 1e3
}

/// The variables (indices into `names`) of the phase portrait: q and s in
/// the Liénard plane, else `plot.phase`, else the first two recorded state
/// variables (or time and the only one).
fn phase_pair(scene: &Scene, names: &[&str]) -> Option<(usize, usize)> {
    if scene.plot.lienard_plane {
        let q = names.iter().position(|n| *n == "q");
        let s = names.iter().position(|n| *n == "s");
        if let (Some(q), Some(s)) = (q, s) {
            return Some((q, s));
        }
    }
    match &scene.plot.phase {
        Some((x, y)) => Some((
            names.iter().position(|n| n == x)?,
            names.iter().position(|n| n == y)?,
        )),
        None => {
            let state: Vec<usize> = (0..names.len()).filter(|k| names[*k] != "t").collect();
            match state.len() {
                0 => None,
                1 => Some((
                    names.iter().position(|n| *n == "t").unwrap_or(state[0]),
                    state[0],
                )),
                _ => Some((state[0], state[1])),
            }
        }
    }
}

/// The variables (indices into `names`) of the Poincaré portrait:
/// `plot.poincare`, else the first two recorded state variables.
fn poincare_pair(scene: &Scene, names: &[&str]) -> (usize, usize) {
    match &scene.plot.poincare {
        Some((x, y)) => (
            names.iter().position(|n| n == x).unwrap_or(0),
            names.iter().position(|n| n == y).unwrap_or(1),
        ),
        None => {
            let state: Vec<usize> = (0..names.len()).filter(|k| names[*k] != "t").collect();
            if state.len() >= 2 {
                (state[0], state[1])
            } else {
                (0, 1)
            }
        }
    }
}

/// An angle wrapped as `plot.wrap_x` asks.
fn wrap(wrap_x: Option<&str>, x: f64) -> f64 {
    match wrap_x {
        Some("2pi") => x.rem_euclid(2.0 * PI),
        Some("pi") => (x + PI).rem_euclid(2.0 * PI) - PI,
        _ => x,
    }
}

/// The colours of a portrait. Few orbits: one colour each. More than the
/// palette's ten: up to ten colour bands along the last varying axis (the
/// orbits of an area-preserving map fill the plane evenly, so a single
/// density would show no structure).
struct Bands {
    per_orbit: bool,
    axis: Option<usize>,
    count: usize,
}

impl Bands {
    fn of(n: usize, varying: &[usize], shape: &[usize]) -> Self {
        let per_orbit = n <= 10;
        let axis = varying.last().copied();
        let count = match (per_orbit, axis) {
            (true, _) => n,
            (false, Some(k)) => shape[k].min(10),
            (false, None) => 1,
        };
        Self {
            per_orbit,
            axis,
            count,
        }
    }

    /// The band of orbit `i`.
    fn of_orbit(&self, i: usize, shape: &[usize], strides: &[usize]) -> usize {
        match (self.per_orbit, self.axis) {
            (true, _) => i,
            (false, Some(k)) => (i / strides[k]) % shape[k] * self.count / shape[k],
            (false, None) => 0,
        }
    }

    /// The legend of band `b`: the orbit, the range of the axis, or the count.
    fn label(&self, b: usize, p: &Pictures) -> String {
        match (self.per_orbit, self.axis) {
            (true, _) => p.trajectory_label(b),
            (false, Some(k)) => {
                let v = &p.scene.axes[k].values;
                let (first, last) = (b * v.len() / self.count, (b + 1) * v.len() / self.count - 1);
                let (lo, hi) = (p.axis_value(k, v[first]), p.axis_value(k, v[last]));
                if first == last {
                    format!("{} = {lo}", p.scene.axes[k].name)
                } else {
                    format!("{} ∈ [{lo}, {hi}]", p.scene.axes[k].name)
                }
            }
            (false, None) => format!("{} orbits", p.n),
        }
    }
}

/// Value `v` of an axis over `values`, with four significant digits or as
/// many more as tell the axis's values apart (1.121 and 1.1209, not 1.121
/// twice).
#[cfg(test)]
fn axis_value(values: &[f64], v: f64) -> String {
    fmt_significant(v, axis_digits(values))
}

/// The significant digits of [`axis_value`] for an axis over `values`.
fn axis_digits(values: &[f64]) -> usize {
    let mut sorted = ascending(values).into_owned();
    sorted.dedup();
    // Rounding keeps the order: two values that print alike are neighbours.
    let distinct = |d: usize| {
        let mut last = None;
        sorted.iter().all(|x| {
            let s = fmt_significant(*x, d);
            last.replace(s.clone()) != Some(s)
        })
    };
    (4..=15).find(|d| distinct(*d)).unwrap_or(17)
}

impl Pictures<'_> {
    /// Value `v` of axis `k` as [`axis_value`] writes it.
    fn axis_value(&self, k: usize, v: f64) -> String {
        let digits = self.digits[k].get_or_init(|| axis_digits(&self.scene.axes[k].values));
        fmt_significant(v, *digits)
    }

    /// "epsilon = 0.5, q = 2" for trajectory `i`.
    fn trajectory_label(&self, i: usize) -> String {
        self.scene
            .axes
            .iter()
            .enumerate()
            .filter(|(_, a)| a.values.len() > 1)
            .map(|(k, a)| {
                let v = a.values[(i / self.strides[k]) % a.values.len()];
                format!("{} = {}", a.name, self.axis_value(k, v))
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spread_of_round_off_is_named() {
        let f32s = ("f32", f64::from(f32::EPSILON) / 2.0);
        let f64s = ("f64", f64::EPSILON / 2.0);
        // lienard_quartic's cycle periods in f32: 8 units in the last place.
        let period = [5.745556, 5.745554, 5.745558, 5.745555];
        let label = round_off_label("cycle period", &period, f32s);
        assert_eq!(label, "cycle period (spread 4.0e-6: f32 round-off)");
        assert_eq!(
            round_off_label("cycle period", &period, f64s),
            "cycle period"
        );
        let flat = [2.0, 2.0, f64::NAN];
        assert_eq!(round_off_label("q", &flat, f32s), "q");
    }

    #[test]
    fn axis_values_keep_the_digits_that_tell_them_apart() {
        // spin_orbit_resonant_lambda0.001's initial p: 1.121 twice at 4 digits.
        let p = [1.137, 1.121, 1.1209, 1.112, 1.0, 0.96, 0.91, 0.876375, 0.86];
        assert_eq!(axis_value(&p, 1.1209), "1.1209");
        assert_eq!(axis_value(&p, 1.121), "1.121");
        assert_eq!(axis_value(&p, 1.0), "1");
        assert_eq!(axis_value(&[0.01, 2.0, 5.0], 0.01), "0.01");
        assert_eq!(axis_value(&[1e-4, 5e-4], 1e-4), "1e-4");
    }
}
