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
use crate::plan::observations::{Col, Column, File, Observations, Status};
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
/// whole), in the order of its columns' declaration: final values,
/// trajectories, Poincaré points and counts, cycle statistics, means and
/// resonances, indicators, status. Listing needs a row: with `obs.n = 0`
/// no column could tell present from absent.
pub fn arrays<'a, R: Real>(scene: &Scene, obs: &'a Observations<R>) -> Result<Vec<Array<'a>>> {
    let mut out = vec![];
    for (file, column) in obs.files() {
        match column {
            Column::Named(arrays) => {
                for v in out_vars(scene, file.field) {
                    out.push(var(v, arrays, file, obs)?);
                }
            }
            Column::Plain(values) if !values.is_empty() => out.push(plain(file, obs, values)),
            Column::Plain(_) => {}
        }
        if let (Some(r), "mean") = (&scene.observers.resonance, file.field) {
            out.push(owned(scalar("resonance.npy", "<i4", &resonance(r, obs)?)));
        }
    }
    let (status, step) = status_bytes(obs);
    out.push(array_of("status.npy", "|u1", Cow::Owned(status)));
    out.push(array_of("status_step.npy", "<i8", Cow::Owned(step)));
    Ok(out)
}

/// The bytes of `status` (0 ok, 1 non-finite, 2 stopped) and `status_step`
/// (the step it became non-finite or stopped after; −1: neither), made on
/// every core.
fn status_bytes<R: Real>(obs: &Observations<R>) -> (Vec<u8>, Vec<u8>) {
    use rayon::prelude::*;
    let (mut status, mut step) = (vec![0u8; obs.n], vec![0u8; 8 * obs.n]);
    status
        .par_iter_mut()
        .zip(step.par_chunks_exact_mut(8))
        .enumerate()
        .for_each(|(i, (s, k))| {
            let (code, at) = match obs.status(i) {
                Status::Ok => (0, -1),
                Status::NonFinite { step } => (1, step as i64),
                Status::Stopped { step } => (2, step as i64),
            };
            *s = code;
            k.copy_from_slice(&at.to_le_bytes());
        });
    (status, step)
}

/// The scene's variables of a named column (vectors whole, as the scene
/// names them); none where the scene does not ask for the column.
pub fn out_vars<'s>(scene: &'s Scene, field: &str) -> &'s [OutVar] {
    let o = &scene.observers;
    match field {
        "final_values" => &o.final_vars,
        "trajectory" => o.trajectory.as_ref().map_or(&[], |t| &t.vars),
        "poincare" => o.poincare.as_ref().map_or(&[], |p| &p.vars),
        "mean" => o.average.as_ref().map_or(&[], |a| &a.vars),
        "attractor_points" => o.attractors.as_ref().map_or(&[], |a| &a.vars),
        _ => &[],
    }
}

/// A plain column's array.
fn plain<'a, R: Real>(file: File, obs: &Observations<R>, values: Col<'a, R>) -> Array<'a> {
    let (descr, bytes): (_, &[u8]) = match values {
        Col::Real(v) => (real::<R>(), bytemuck::cast_slice(v)),
        Col::Count(v) => ("<u4", bytemuck::cast_slice(v)),
        Col::Int(v) => ("<i4", bytemuck::cast_slice(v)),
    };
    let (inner, inner_names) = file.inner(obs);
    Array {
        file: file.npy(None),
        descr,
        inner,
        inner_names,
        bytes: Cow::Borrowed(bytes),
    }
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
    array_of(file, descr, Cow::Borrowed(bytemuck::cast_slice(data)))
}

/// A one-value-per-trajectory array of `bytes`.
fn array_of<'a>(file: &str, descr: &'static str, bytes: Cow<'a, [u8]>) -> Array<'a> {
    Array {
        file: file.into(),
        descr,
        inner: vec![],
        inner_names: vec![],
        bytes,
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

/// `<name>_<var>.npy` of output variable `v`, with a trailing component
/// axis for vectors (Kepler's `q` is `[q1, q2]`).
fn var<'a, R: Real>(
    v: &OutVar,
    arrays: &'a [(String, Vec<R>)],
    file: File,
    obs: &Observations<R>,
) -> Result<Array<'a>> {
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
    let (mut dims, mut names) = file.inner(obs);
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
    Ok(Array {
        file: file.npy(Some(&v.name)),
        descr: real::<R>(),
        inner: dims,
        inner_names: names,
        bytes,
    })
}
