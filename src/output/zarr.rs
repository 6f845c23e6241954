//! The run as a Zarr v3 store, `DIR/run.zarr` (`[output] format = "zarr"`
//! or `--format zarr`): one array per `.npy` of the same name, chunked as
//! the run is (`chunks.rs`: each chunk of the run is one chunk of every
//! array, written whole by the process that integrated it, so shards need
//! no lock), dimensions named after the scene's axes and then `frame`,
//! `point`, `component`; the axes' values as coordinate arrays named after
//! them; the resolved scene and the summary as the group's attributes. This
//! is what `xarray.open_zarr` reads as a labelled Dataset.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};
use zarrs::array::{data_type, ArrayBuilder, ArrayBytes, DataType};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::GroupBuilder;

use crate::output::arrays::Array;
use crate::output::chunks::Chunks;
use crate::scene::Scene;

/// The store's folder in the run directory.
pub const STORE: &str = "run.zarr";

/// The arrays of a store, open for writing chunks.
pub struct Store {
    arrays: Vec<zarrs::array::Array<FilesystemStore>>,
    path: std::path::PathBuf,
}

/// The Zarr type and fill value of a numpy type string.
fn zarr_type(descr: &str) -> (DataType, f64) {
    match descr {
        "<f4" => (data_type::float32(), f64::NAN),
        "<f8" => (data_type::float64(), f64::NAN),
        "|u1" => (data_type::uint8(), 0.0),
        "<u4" => (data_type::uint32(), 0.0),
        _ => (data_type::int64(), -1.0),
    }
}

fn fill(descr: &str, v: f64) -> zarrs::array::FillValue {
    match descr {
        "<f4" => (v as f32).into(),
        "<f8" => v.into(),
        "|u1" => (v as u8).into(),
        "<u4" => (v as u32).into(),
        _ => (v as i64).into(),
    }
}

impl Store {
    /// Opens the store in `dir`, creating its group and arrays (metadata
    /// only) when absent; every shard creates the same metadata.
    pub fn open(dir: &Path, scene: &Scene, list: &[Array], chunks: &Chunks) -> Result<Store> {
        let path = dir.join(STORE);
        std::fs::create_dir_all(&path).with_context(|| format!("creating {}", path.display()))?;
        let fs = Arc::new(
            FilesystemStore::new(&path).with_context(|| format!("opening {}", path.display()))?,
        );
        let shape = scene.shape();
        let axis_names: Vec<String> = scene.axes.iter().map(|a| a.name.clone()).collect();
        let mut arrays = vec![];
        for a in list {
            let full: Vec<u64> = a.shape(&shape);
            let mut chunk: Vec<u64> = chunk_shape(chunks);
            chunk.extend(&a.inner);
            let (dtype, f) = zarr_type(a.descr);
            let mut dims: Vec<String> = axis_names.clone();
            dims.extend(a.inner_names.iter().map(|s| s.to_string()));
            let name = a.file.trim_end_matches(".npy");
            let array = ArrayBuilder::new(full, chunk, dtype, fill(a.descr, f))
                .dimension_names(Some(dims))
                .build(fs.clone(), &format!("/{name}"))
                .with_context(|| format!("{}: array {name}", path.display()))?;
            if !path.join(name).join("zarr.json").exists() {
                array
                    .store_metadata()
                    .with_context(|| format!("writing {}/{name}", path.display()))?;
            }
            arrays.push(array);
        }
        Ok(Store { arrays, path })
    }

    /// Writes chunk `k` of the run (`list` holds its rows) into every array.
    pub fn write_chunk(&self, chunks: &Chunks, k: usize, list: &[Array]) -> Result<()> {
        let mut index = chunk_index(chunks, k);
        for (array, a) in self.arrays.iter().zip(list) {
            index.truncate(chunks.shape.len().max(1));
            index.resize(array.dimensionality(), 0);
            let subset = array
                .chunk_subset_bounded(&index)
                .with_context(|| format!("{}: chunk {k}", self.path.display()))?;
            array
                .store_array_subset(&subset, ArrayBytes::new_flen(a.bytes.to_vec()))
                .with_context(|| format!("writing {} chunk {k}", a.file))?;
        }
        Ok(())
    }
}

/// The chunk shape over the scene's axes (one axis of no values: `[1]`).
fn chunk_shape(c: &Chunks) -> Vec<u64> {
    (0..c.shape.len())
        .map(|k| match k.cmp(&c.axis) {
            std::cmp::Ordering::Less => 1,
            std::cmp::Ordering::Equal => c.along as u64,
            std::cmp::Ordering::Greater => c.shape[k] as u64,
        })
        .collect()
}

/// The Zarr chunk index of run chunk `k` over the scene's axes.
fn chunk_index(c: &Chunks, k: usize) -> Vec<u64> {
    let per_run = c.shape.get(c.axis).map_or(1, |n| n.div_ceil(c.along));
    let (mut outer, j) = (k / per_run, k % per_run);
    let mut index = vec![0u64; c.shape.len()];
    for a in (0..c.axis.min(c.shape.len())).rev() {
        index[a] = (outer % c.shape[a]) as u64;
        outer /= c.shape[a];
    }
    if let Some(x) = index.get_mut(c.axis) {
        *x = j as u64;
    }
    index
}

/// Writes the axes as coordinate arrays and the group with `attributes`
/// (the resolved scene and the summary): the last step of a run.
pub fn finish(dir: &Path, scene: &Scene, attributes: serde_json::Value) -> Result<()> {
    let path = dir.join(STORE);
    let fs = Arc::new(
        FilesystemStore::new(&path).with_context(|| format!("opening {}", path.display()))?,
    );
    for ax in &scene.axes {
        let n = ax.values.len() as u64;
        let array = ArrayBuilder::new(vec![n], vec![n.max(1)], data_type::float64(), f64::NAN)
            .dimension_names(Some([ax.name.clone()]))
            .build(fs.clone(), &format!("/{}", ax.name))
            .with_context(|| format!("{}: axis {}", path.display(), ax.name))?;
        array.store_metadata()?;
        array
            .store_chunk(&[0], &ax.values)
            .with_context(|| format!("writing {}/{}", path.display(), ax.name))?;
    }
    let attrs = match attributes {
        serde_json::Value::Object(m) => m,
        other => [("reeb".to_string(), other)].into_iter().collect(),
    };
    GroupBuilder::new()
        .attributes(attrs)
        .build(fs, "/")
        .with_context(|| format!("{}: group", path.display()))?
        .store_metadata()
        .with_context(|| format!("writing {}/zarr.json", path.display()))
}

/// The whole data of array `name` of the store in `dir`, as stored bytes.
pub fn read(dir: &Path, name: &str) -> Result<Vec<u8>> {
    let path = dir.join(STORE);
    let fs = Arc::new(
        FilesystemStore::new(&path).with_context(|| format!("opening {}", path.display()))?,
    );
    let array = zarrs::array::Array::open(fs, &format!("/{name}"))
        .with_context(|| format!("opening {}/{name}", path.display()))?;
    let bytes: ArrayBytes<'static> = array
        .retrieve_array_subset(&array.subset_all())
        .with_context(|| format!("reading {}/{name}", path.display()))?;
    Ok(bytes
        .into_fixed()
        .with_context(|| format!("reading {}/{name}", path.display()))?
        .into_owned())
}
