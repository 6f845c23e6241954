//! The arrays of a run directory (`.npy`): axis values, final values,
//! trajectories, Poincaré points, cycle statistics, time averages and
//! resonances, chaos indicators, status. Every array's
//! leading dimensions are the scene's axes, in file order, so the rows of a
//! chunk of trajectories are one contiguous slab of each (`npy.rs`).

use std::borrow::Cow;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result};

use crate::num::precision::Real;
use crate::output::npy;
use crate::plan::observations::{Observations, Status};
use crate::plan::observers::ResonanceObs;
use crate::scene::{OutVar, Scene};

/// Writes a C-order .npy array of `data` (as many elements as `shape` holds).
pub fn write_npy<T: npy::Element>(
    path: &Path,
    shape: &[u64],
    data: impl IntoIterator<Item = T>,
) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let write = || -> std::io::Result<()> {
        let mut w = BufWriter::new(file);
        w.write_all(&npy::whole_header(T::DESCR, shape))?;
        for x in data {
            w.write_all(bytemuck::bytes_of(&x))?;
        }
        w.flush()
    };
    write().with_context(|| format!("writing {}", path.display()))
}

/// Writes the axis values, `axis_<name>.npy`; returns the file names.
pub fn write_axes(scene: &Scene, dir: &Path) -> Result<Vec<String>> {
    let mut files = vec![];
    for ax in &scene.axes {
        let name = format!("axis_{}.npy", ax.name);
        write_npy(
            &dir.join(&name),
            &[ax.values.len() as u64],
            ax.values.iter().copied(),
        )?;
        files.push(name);
    }
    Ok(files)
}

/// One per-trajectory array of a run: its file, numpy type, the dimensions
/// after the scene's axes, and the rows a set of observations holds (the
/// observations' own memory where the layout is the same).
pub struct Array<'a> {
    pub file: String,
    pub descr: &'static str,
    pub inner: Vec<u64>,
    /// The names of the `inner` dimensions: `frame`, `point`, `component`.
    pub inner_names: Vec<&'static str>,
    pub bytes: Cow<'a, [u8]>,
}

impl Array<'_> {
    /// The full shape, for a scene of `shape`.
    pub fn shape(&self, shape: &[usize]) -> Vec<u64> {
        shape
            .iter()
            .map(|s| *s as u64)
            .chain(self.inner.clone())
            .collect()
    }
}

/// Every per-trajectory array of `obs` (a chunk of a scene's rows, or the
/// whole), in file order: final values, trajectories, Poincaré points and
/// counts, cycle statistics, status. With `obs.n = 0` it lists the arrays
/// (their bytes empty).
pub fn arrays<'a, R: Real>(scene: &Scene, obs: &'a Observations<R>) -> Result<Vec<Array<'a>>> {
    let mut out = vec![];
    vars(&scene.final_vars, &obs.final_values, 0, "final", &mut out)?;
    if let Some((_, vs)) = &scene.trajectory {
        vars(vs, &obs.trajectory, obs.frames, "trajectory", &mut out)?;
    }
    if let Some((_, vs, _)) = &scene.poincare {
        vars(vs, &obs.poincare, obs.max_points, "poincare", &mut out)?;
        out.push(scalar("poincare_count.npy", "<u4", &obs.poincare_count));
    }
    if scene.cycle.is_some() {
        out.push(scalar(
            "cycle_amplitude.npy",
            real::<R>(),
            &obs.cycle_amplitude,
        ));
        out.push(scalar("cycle_period.npy", real::<R>(), &obs.cycle_period));
    }
    if let Some((vs, _)) = &scene.average {
        vars(vs, &obs.mean, 0, "mean", &mut out)?;
    }
    if let Some(r) = &scene.resonance {
        out.push(owned(scalar("resonance.npy", "<i4", &resonance(r, obs)?)));
    }
    if scene.lyapunov.is_some() {
        out.push(Array {
            inner: vec![obs.exponents as u64],
            inner_names: vec!["exponent"],
            ..scalar("lyapunov.npy", real::<R>(), &obs.lyapunov)
        });
    }
    if scene.fli.is_some() {
        out.push(scalar("fli.npy", real::<R>(), &obs.fli));
    }
    if scene.megno.is_some() {
        out.push(scalar("megno.npy", real::<R>(), &obs.megno));
    }
    if scene.sali.is_some() {
        out.push(scalar("sali.npy", real::<R>(), &obs.sali));
    }
    if scene.gali.is_some() {
        out.push(scalar("gali.npy", real::<R>(), &obs.gali));
    }
    out.extend(indicator_frames(scene, obs));
    // status: 0 ok, 1 non-finite, 2 stopped; status_step: the step it
    // became non-finite or stopped after (−1: neither).
    let (status, step): (Vec<u8>, Vec<i64>) = (0..obs.n)
        .map(|i| match obs.status(i) {
            Status::Ok => (0, -1),
            Status::NonFinite { step } => (1, step as i64),
            Status::Stopped { step } => (2, step as i64),
        })
        .unzip();
    out.push(owned(scalar("status.npy", "|u1", &status)));
    out.push(owned(scalar("status_step.npy", "<i8", &step)));
    Ok(out)
}

/// The indicators' running values per trajectory frame:
/// `trajectory_lyapunov.npy` (axes × frame × exponent),
/// `trajectory_fli.npy`, `trajectory_megno.npy`, `trajectory_sali.npy`,
/// `trajectory_gali.npy` (axes × frame).
fn indicator_frames<'a, R: Real>(scene: &Scene, obs: &'a Observations<R>) -> Vec<Array<'a>> {
    let mut out = vec![];
    if scene.trajectory.is_none() || obs.frames == 0 {
        return out;
    }
    let framed = |file: &str, data: &'a [R]| Array {
        inner: vec![obs.frames as u64],
        inner_names: vec!["frame"],
        ..scalar(file, real::<R>(), data)
    };
    if scene.lyapunov.is_some() {
        let mut a = framed("trajectory_lyapunov.npy", &obs.trajectory_lyapunov);
        a.inner.push(obs.exponents as u64);
        a.inner_names.push("exponent");
        out.push(a);
    }
    if scene.fli.is_some() {
        out.push(framed("trajectory_fli.npy", &obs.trajectory_fli));
    }
    if scene.megno.is_some() {
        out.push(framed("trajectory_megno.npy", &obs.trajectory_megno));
    }
    if scene.sali.is_some() {
        out.push(framed("trajectory_sali.npy", &obs.trajectory_sali));
    }
    if scene.gali.is_some() {
        out.push(framed("trajectory_gali.npy", &obs.trajectory_gali));
    }
    out
}

/// Each trajectory's resonance: the index into `r.ratios` of the one its
/// mean of `r.var` is captured in, −1 for none (a NaN mean included).
pub fn resonance<R: Real>(r: &ResonanceObs, obs: &Observations<R>) -> Result<Vec<i32>> {
    let mean = obs
        .mean_of(&r.var)
        .with_context(|| format!("the average of {}", r.var))?;
    Ok(mean.iter().map(|m| r.classify(m.to_f64())).collect())
}

/// The numpy type of the working precision.
fn real<R: Real>() -> &'static str {
    if std::mem::size_of::<R>() == 4 {
        "<f4"
    } else {
        "<f8"
    }
}

/// One value per trajectory. (Little-endian: reeb runs on x86-64 and
/// aarch64.)
fn scalar<'a, T: bytemuck::Pod>(file: &str, descr: &'static str, data: &'a [T]) -> Array<'a> {
    Array {
        file: file.into(),
        descr,
        inner: vec![],
        inner_names: vec![],
        bytes: Cow::Borrowed(bytemuck::cast_slice(data)),
    }
}

/// `a` owning its bytes (made from a temporary).
fn owned(a: Array) -> Array<'static> {
    Array {
        bytes: Cow::Owned(a.bytes.into_owned()),
        file: a.file,
        descr: a.descr,
        inner: a.inner,
        inner_names: a.inner_names,
    }
}

/// `<prefix>_<var>.npy` per output variable, `inner` values per trajectory
/// (frames, points; 0: one), a trailing component axis for vectors
/// (Kepler's `q` is `[q1, q2]`).
fn vars<'a, R: Real>(
    vars: &[OutVar],
    arrays: &'a [(String, Vec<R>)],
    inner: usize,
    prefix: &str,
    out: &mut Vec<Array<'a>>,
) -> Result<()> {
    for v in vars {
        let comps: Vec<&'a Vec<R>> = v
            .components
            .iter()
            .map(|c| {
                arrays
                    .iter()
                    .find(|(n, _)| n == c)
                    .map(|(_, x)| x)
                    .context("recorded component")
            })
            .collect::<Result<_>>()?;
        let mut dims = if inner > 0 {
            vec![inner as u64]
        } else {
            vec![]
        };
        let per = if prefix == "poincare" {
            "point"
        } else {
            "frame"
        };
        let mut names = if inner > 0 { vec![per] } else { vec![] };
        let bytes = if comps.len() == 1 {
            Cow::Borrowed(bytemuck::cast_slice(comps[0].as_slice()))
        } else {
            dims.push(comps.len() as u64);
            names.push("component");
            let len = comps[0].len();
            let values: Vec<R> = (0..len)
                .flat_map(|i| comps.iter().map(move |c| c[i]))
                .collect();
            Cow::Owned(bytemuck::cast_slice(&values).to_vec())
        };
        out.push(Array {
            file: format!("{prefix}_{}.npy", v.name),
            descr: real::<R>(),
            inner: dims,
            inner_names: names,
            bytes,
        });
    }
    Ok(())
}
