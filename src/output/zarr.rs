//! The run as a Zarr v3 store, `DIR/run.zarr` (`[output] format = "zarr"`
//! or `--format zarr`): one array per `.npy` of the same name, chunked as
//! the run is (`chunks.rs`: each chunk of the run is one chunk of every
//! array, written whole by the process that integrated it, so shards need
//! no lock), dimensions named after the scene's axes and then `frame`,
//! `point`, `component`; the axes' values as coordinate arrays named after
//! them; the resolved scene and the summary as the group's attributes. This
//! is what `xarray.open_zarr` reads as a labelled Dataset.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result};
use zarrs::array::{data_type, ArrayBuilder, ArrayBytes, DataType, FillValue};
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
    path: PathBuf,
}

/// The Zarr type and fill value (NaN, or 0, or −1 for "never" and "no
/// resonance") of a numpy type string.
fn zarr_type(descr: &str) -> (DataType, FillValue) {
    match descr {
        "<f4" => (data_type::float32(), f32::NAN.into()),
        "<f8" => (data_type::float64(), f64::NAN.into()),
        "|u1" => (data_type::uint8(), 0u8.into()),
        "<u4" => (data_type::uint32(), 0u32.into()),
        "<i4" => (data_type::int32(), (-1i32).into()),
        "<i8" => (data_type::int64(), (-1i64).into()),
        other => unreachable!("an array of numpy type {other}: add it here"),
    }
}

/// The store of `dir` (`DIR/run.zarr`) and its path.
fn filesystem(dir: &Path) -> Result<(PathBuf, Arc<FilesystemStore>)> {
    let path = dir.join(STORE);
    let fs = FilesystemStore::new(&path).with_context(|| format!("opening {}", path.display()))?;
    Ok((path, Arc::new(fs)))
}

impl Store {
    /// Opens the store in `dir`, creating its group and arrays (metadata
    /// only) when absent; every shard creates the same metadata.
    pub fn open(dir: &Path, scene: &Scene, list: &[Array], chunks: &Chunks) -> Result<Store> {
        let store = dir.join(STORE);
        std::fs::create_dir_all(&store).with_context(|| format!("creating {}", store.display()))?;
        let (path, fs) = filesystem(dir)?;
        let shape = scene.shape();
        let axis_names: Vec<String> = scene.axes.iter().map(|a| a.name.clone()).collect();
        let mut arrays = vec![];
        for a in list {
            let full: Vec<u64> = a.shape(&shape);
            let mut chunk = chunks.chunk_shape();
            chunk.extend(&a.inner);
            let (dtype, fill) = zarr_type(a.descr);
            let mut dims: Vec<String> = axis_names.clone();
            dims.extend(a.inner_names.iter().map(|s| s.to_string()));
            let name = a.file.trim_end_matches(".npy");
            let array = ArrayBuilder::new(full, chunk, dtype, fill)
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
        for (array, a) in self.arrays.iter().zip(list) {
            let subset = self.subset(array, chunks, k)?;
            array
                .store_array_subset(&subset, ArrayBytes::new_flen(a.bytes.to_vec()))
                .with_context(|| format!("writing {} chunk {k}", a.file))?;
        }
        Ok(())
    }

    /// The bytes chunk `k` of the run holds in every array (a missing chunk
    /// file reads as its fill value).
    pub fn read_chunk(&self, chunks: &Chunks, k: usize, list: &[Array]) -> Result<Vec<Vec<u8>>> {
        self.arrays
            .iter()
            .zip(list)
            .map(|(array, a)| {
                let subset = self.subset(array, chunks, k)?;
                let bytes: ArrayBytes<'static> = array
                    .retrieve_array_subset(&subset)
                    .with_context(|| format!("reading {} chunk {k}", a.file))?;
                Ok(bytes
                    .into_fixed()
                    .with_context(|| format!("reading {} chunk {k}", a.file))?
                    .into_owned())
            })
            .collect()
    }

    /// The elements of chunk `k` of the run in `array`.
    fn subset(
        &self,
        array: &zarrs::array::Array<FilesystemStore>,
        chunks: &Chunks,
        k: usize,
    ) -> Result<zarrs::array::ArraySubset> {
        let mut index = chunks.grid_index(k);
        index.truncate(chunks.shape.len().max(1));
        index.resize(array.dimensionality(), 0);
        array
            .chunk_subset_bounded(&index)
            .with_context(|| format!("{}: chunk {k}", self.path.display()))
    }
}

/// Writes the axes as coordinate arrays and the group with `attributes`
/// (the resolved scene and the summary): the last step of a run.
pub fn finish(dir: &Path, scene: &Scene, attributes: serde_json::Value) -> Result<()> {
    let (path, fs) = filesystem(dir)?;
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
    let (path, fs) = filesystem(dir)?;
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
