//! The arrays of a run directory (`.npy`): axis values, final values,
//! trajectories, Poincaré points, cycle statistics, status. Every array's
//! leading dimensions are the scene's axes, in file order.

use std::io::BufWriter;
use std::path::Path;

use anyhow::{Context, Result};
use npyz::WriterBuilder;

use crate::models::Flows;
use crate::plan::observations::Observations;
use crate::scene::{OutVar, Scene};

/// Writes a C-order .npy array.
pub fn write_npy<T: npyz::AutoSerialize + npyz::Serialize>(
    path: &Path,
    shape: &[u64],
    data: impl IntoIterator<Item = T>,
) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let write = || -> std::io::Result<()> {
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(BufWriter::new(file))
            .begin_nd()?;
        w.extend(data)?;
        w.finish()
    };
    write().with_context(|| format!("writing {}", path.display()))
}

/// Writes every array of `obs` into `dir`; returns the file names.
pub fn write_arrays<R: Flows>(
    scene: &Scene,
    dir: &Path,
    obs: &Observations<R>,
) -> Result<Vec<String>> {
    let w = Writer {
        dir,
        shape: scene.shape().iter().map(|s| *s as u64).collect(),
    };
    let mut files: Vec<String> = vec![];
    for ax in &scene.axes {
        let name = format!("axis_{}.npy", ax.name);
        write_npy(
            &dir.join(&name),
            &[ax.values.len() as u64],
            ax.values.iter().copied(),
        )?;
        files.push(name);
    }
    w.vars(&scene.final_vars, &obs.final_values, 0, "final", &mut files)?;
    if let Some((_, vars)) = &scene.trajectory {
        w.vars(vars, &obs.trajectory, obs.frames, "trajectory", &mut files)?;
    }
    if let Some((_, vars, _)) = &scene.poincare {
        w.vars(vars, &obs.poincare, obs.max_points, "poincare", &mut files)?;
        w.per_trajectory(
            "poincare_count.npy",
            obs.poincare_count.iter().copied(),
            &mut files,
        )?;
    }
    if scene.cycle.is_some() {
        w.per_trajectory(
            "cycle_amplitude.npy",
            obs.cycle_amplitude.iter().copied(),
            &mut files,
        )?;
        w.per_trajectory(
            "cycle_period.npy",
            obs.cycle_period.iter().copied(),
            &mut files,
        )?;
    }
    // status: 0 ok, 1 non-finite; status_step: the step it became non-finite (−1: never).
    let steps = &obs.nonfinite_step;
    w.per_trajectory(
        "status.npy",
        steps.iter().map(|s| u8::from(*s != 0)),
        &mut files,
    )?;
    let step_or_never = |s: &u32| if *s == 0 { -1i64 } else { *s as i64 };
    w.per_trajectory(
        "status_step.npy",
        steps.iter().map(step_or_never),
        &mut files,
    )?;
    Ok(files)
}

/// Writes arrays of the scene's shape (plus trailing dimensions) into a directory.
struct Writer<'a> {
    dir: &'a Path,
    shape: Vec<u64>,
}

impl Writer<'_> {
    fn dims(&self, extra: &[u64]) -> Vec<u64> {
        self.shape.iter().chain(extra).copied().collect()
    }

    /// One value per trajectory.
    fn per_trajectory<T: npyz::AutoSerialize + npyz::Serialize>(
        &self,
        name: &str,
        data: impl IntoIterator<Item = T>,
        files: &mut Vec<String>,
    ) -> Result<()> {
        write_npy(&self.dir.join(name), &self.dims(&[]), data)?;
        files.push(name.to_string());
        Ok(())
    }

    /// `<prefix>_<var>.npy` per output variable, `inner` values per
    /// trajectory (frames, points; 0: one), a trailing component axis for
    /// vectors (Kepler's `q` is `[q1, q2]`).
    fn vars<R: Flows>(
        &self,
        vars: &[OutVar],
        arrays: &[(String, Vec<R>)],
        inner: usize,
        prefix: &str,
        files: &mut Vec<String>,
    ) -> Result<()> {
        for v in vars {
            let comps: Vec<&Vec<R>> = v
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
            let inner_dims = [inner as u64];
            let mut dims = self.dims(if inner > 0 { &inner_dims } else { &[] });
            let name = format!("{prefix}_{}.npy", v.name);
            if comps.len() == 1 {
                write_npy(&self.dir.join(&name), &dims, comps[0].iter().copied())?;
            } else {
                dims.push(comps.len() as u64);
                let len = comps[0].len();
                let interleaved = (0..len).flat_map(|i| comps.iter().map(move |c| c[i]));
                write_npy(&self.dir.join(&name), &dims, interleaved)?;
            }
            files.push(name);
        }
        Ok(())
    }
}
