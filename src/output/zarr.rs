//! The run as a Zarr v3 store, `DIR/run.zarr` (`[output] format = "zarr"`
//! or `--format zarr`): one array per `.npy` of the same name, chunked as
//! the run is (`chunks.rs`: each chunk of the run is one chunk of every
//! array, written whole by the process that integrated it, so shards need
//! no lock), dimensions named after the scene's axes and then `frame`,
//! `point`, `component`; the axes' values as coordinate arrays named after
//! them; the resolved scene and the summary as the group's attributes. This
//! is what `xarray.open_zarr` reads as a labelled Dataset.
//!
//! Written by reeb itself, as the specification (zarr-specs, v3.0) lays
//! it out: uncompressed chunks (the `bytes` codec, little-endian) in files
//! `NAME/c/i/j/…` under the default chunk-key encoding, each the whole
//! chunk shape (an edge chunk padded with the fill value), and each node's
//! metadata in `zarr.json`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::{json, Value};

use crate::output::arrays::Array;
use crate::output::chunks::Chunks;
use crate::scene::Scene;

/// The store's folder in the run directory.
pub const STORE: &str = "run.zarr";

/// The metadata file of every node.
const METADATA: &str = "zarr.json";

/// One array of a store: its folder, shape, chunk shape and element.
#[derive(Debug, Clone)]
struct Meta {
    dir: PathBuf,
    shape: Vec<u64>,
    chunk: Vec<u64>,
    item: usize,
    fill: Vec<u8>,
}

/// The arrays of a store, open for writing chunks.
pub struct Store {
    arrays: Vec<Meta>,
}

/// The Zarr type, the fill value's bytes (NaN, or 0, or −1 for "never" and
/// "no resonance") and its JSON, of a numpy type string.
fn zarr_type(descr: &str) -> (&'static str, Vec<u8>, Value) {
    match descr {
        "<f4" => ("float32", f32::NAN.to_le_bytes().to_vec(), json!("NaN")),
        "<f8" => ("float64", f64::NAN.to_le_bytes().to_vec(), json!("NaN")),
        "|u1" => ("uint8", vec![0], json!(0)),
        "<u4" => ("uint32", 0u32.to_le_bytes().to_vec(), json!(0)),
        "<i4" => ("int32", (-1i32).to_le_bytes().to_vec(), json!(-1)),
        "<i8" => ("int64", (-1i64).to_le_bytes().to_vec(), json!(-1)),
        other => unreachable!("an array of numpy type {other}: add it here"),
    }
}

/// An array's `zarr.json`.
fn array_metadata(shape: &[u64], chunk: &[u64], descr: &str, dims: &[String]) -> Value {
    let (dtype, _, fill) = zarr_type(descr);
    json!({
        "zarr_format": 3,
        "node_type": "array",
        "shape": shape,
        "data_type": dtype,
        "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunk}},
        "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
        "fill_value": fill,
        "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}],
        "attributes": {},
        "dimension_names": dims,
    })
}

/// Writes `value` as `dir/zarr.json`, under a private name and renamed
/// (every shard writes the same metadata; none ever sees half of it).
fn write_metadata(dir: &Path, value: &Value) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(METADATA);
    let tmp = dir.join(format!(".{METADATA}.{}.new", std::process::id()));
    let text = serde_json::to_string_pretty(value)? + "\n";
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, &path))
        .with_context(|| format!("writing {}", path.display()))
}

impl Meta {
    fn new(dir: PathBuf, shape: Vec<u64>, chunk: Vec<u64>, descr: &str) -> Meta {
        let (_, fill, _) = zarr_type(descr);
        Meta {
            dir,
            shape,
            chunk,
            item: fill.len(),
            fill,
        }
    }

    /// The array of `dir` as its `zarr.json` describes it (an array this
    /// module wrote: no codec but `bytes`).
    fn read(dir: &Path) -> Result<Meta> {
        let path = dir.join(METADATA);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        let v: Value =
            serde_json::from_str(&text).with_context(|| format!("reading {}", path.display()))?;
        let numbers =
            |v: &Value| -> Option<Vec<u64>> { v.as_array()?.iter().map(Value::as_u64).collect() };
        let shape = numbers(&v["shape"]);
        let chunk = numbers(&v["chunk_grid"]["configuration"]["chunk_shape"]);
        let descr = match v["data_type"].as_str() {
            Some("float32") => "<f4",
            Some("float64") => "<f8",
            Some("uint8") => "|u1",
            Some("uint32") => "<u4",
            Some("int32") => "<i4",
            Some("int64") => "<i8",
            _ => bail!("{}: not an array reeb wrote", path.display()),
        };
        match (shape, chunk) {
            (Some(s), Some(c)) if s.len() == c.len() => Ok(Meta::new(dir.into(), s, c, descr)),
            _ => bail!("{}: not an array reeb wrote", path.display()),
        }
    }

    /// The file of the chunk at grid position `index`.
    fn chunk_path(&self, index: &[u64]) -> PathBuf {
        let mut p = self.dir.join("c");
        for i in index {
            p.push(i.to_string());
        }
        p
    }

    /// The bytes of a whole chunk.
    fn chunk_bytes(&self) -> usize {
        self.chunk.iter().product::<u64>() as usize * self.item
    }

    /// How far the chunk at `index` reaches along each dimension (an edge
    /// chunk less than the chunk shape).
    fn extent(&self, index: &[u64]) -> Vec<u64> {
        (0..self.shape.len())
            .map(|d| self.chunk[d].min(self.shape[d] - index[d] * self.chunk[d]))
            .collect()
    }

    /// The contiguous runs `(offset in the extent's data, offset in the
    /// whole chunk, bytes)` of the chunk at `index`: its extent's rows
    /// along the last dimension, in C order.
    fn runs(&self, index: &[u64]) -> Vec<(usize, usize, usize)> {
        let extent = self.extent(index);
        let Some((&last, outer)) = extent.split_last() else {
            return vec![(0, 0, self.item)]; // a 0-d array: one element
        };
        let row = last as usize * self.item;
        let count: u64 = outer.iter().product();
        (0..count)
            .map(|r| {
                // Position `r` of the outer dimensions, C order.
                let (mut rest, mut whole) = (r, 0u64);
                let mut stride = self.chunk[outer.len()];
                for d in (0..outer.len()).rev() {
                    whole += (rest % outer[d]) * stride;
                    rest /= outer[d];
                    stride *= self.chunk[d];
                }
                (r as usize * row, whole as usize * self.item, row)
            })
            .collect()
    }

    /// Writes the chunk at `index` from `data`, the elements of its extent
    /// in C order; the rest of the chunk takes the fill value.
    fn write(&self, index: &[u64], data: &[u8]) -> Result<()> {
        let mut whole = self.fill.repeat(self.chunk_bytes() / self.item);
        for (from, to, len) in self.runs(index) {
            whole[to..to + len].copy_from_slice(&data[from..from + len]);
        }
        let path = self.chunk_path(index);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
        }
        std::fs::write(&path, &whole).with_context(|| format!("writing {}", path.display()))
    }

    /// The elements of the extent of the chunk at `index`, in C order (a
    /// chunk never written reads as its fill value).
    fn read_chunk(&self, index: &[u64]) -> Result<Vec<u8>> {
        let path = self.chunk_path(index);
        let whole = match std::fs::read(&path) {
            Ok(b) if b.len() == self.chunk_bytes() => b,
            Ok(_) => bail!("{}: not a whole chunk", path.display()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                self.fill.repeat(self.chunk_bytes() / self.item)
            }
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let extent: u64 = self.extent(index).iter().product();
        let mut out = vec![0u8; extent as usize * self.item];
        for (to, from, len) in self.runs(index) {
            out[to..to + len].copy_from_slice(&whole[from..from + len]);
        }
        Ok(out)
    }

    /// The chunk grid's positions, in C order.
    fn grid(&self) -> Vec<Vec<u64>> {
        let counts: Vec<u64> = (0..self.shape.len())
            .map(|d| self.shape[d].div_ceil(self.chunk[d].max(1)))
            .collect();
        let total: u64 = counts.iter().product();
        (0..total)
            .map(|mut k| {
                let mut index = vec![0; counts.len()];
                for d in (0..counts.len()).rev() {
                    index[d] = k % counts[d];
                    k /= counts[d];
                }
                index
            })
            .collect()
    }

    /// The whole array's elements in C order.
    fn read_all(&self) -> Result<Vec<u8>> {
        let total: u64 = self.shape.iter().product();
        let mut out = vec![0u8; total as usize * self.item];
        let strides = crate::plan::row_major_strides(
            &self.shape.iter().map(|&n| n as usize).collect::<Vec<_>>(),
        );
        for index in self.grid() {
            let data = self.read_chunk(&index)?;
            let extent = self.extent(&index);
            let row = extent.last().map_or(self.item, |&l| l as usize * self.item);
            let outer: u64 = extent[..extent.len().saturating_sub(1)].iter().product();
            for r in 0..outer.max(1) as usize {
                // Where row `r` of the chunk's extent starts in the array.
                let (mut rest, mut at) = (r, 0usize);
                for d in (0..extent.len().saturating_sub(1)).rev() {
                    let len = extent[d] as usize;
                    at += (index[d] * self.chunk[d]) as usize * strides[d]
                        + (rest % len) * strides[d];
                    rest /= len;
                }
                if let Some(d) = extent.len().checked_sub(1) {
                    at += (index[d] * self.chunk[d]) as usize;
                }
                let from = r * row;
                out[at * self.item..at * self.item + row].copy_from_slice(&data[from..from + row]);
            }
        }
        Ok(out)
    }
}

impl Store {
    /// Opens the store in `dir`, creating its arrays' metadata when absent;
    /// every shard writes the same metadata.
    pub fn open(dir: &Path, scene: &Scene, list: &[Array], chunks: &Chunks) -> Result<Store> {
        let store = dir.join(STORE);
        std::fs::create_dir_all(&store).with_context(|| format!("creating {}", store.display()))?;
        let shape = scene.shape();
        let axis_names: Vec<String> = scene.axes.iter().map(|a| a.name.clone()).collect();
        let mut arrays = vec![];
        for a in list {
            let full: Vec<u64> = a.shape(&shape);
            let mut chunk = chunks.chunk_shape();
            chunk.extend(&a.inner);
            let mut dims: Vec<String> = axis_names.clone();
            dims.extend(a.inner_names.iter().map(|s| s.to_string()));
            let folder = store.join(a.file.trim_end_matches(".npy"));
            if !folder.join(METADATA).exists() {
                write_metadata(&folder, &array_metadata(&full, &chunk, a.descr, &dims))?;
            }
            arrays.push(Meta::new(folder, full, chunk, a.descr));
        }
        Ok(Store { arrays })
    }

    /// Writes chunk `k` of the run (`list` holds its rows) into every array.
    pub fn write_chunk(&self, chunks: &Chunks, k: usize, list: &[Array]) -> Result<()> {
        for (array, a) in self.arrays.iter().zip(list) {
            array
                .write(&grid_index(array, chunks, k), &a.bytes)
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
                array
                    .read_chunk(&grid_index(array, chunks, k))
                    .with_context(|| format!("reading {} chunk {k}", a.file))
            })
            .collect()
    }
}

/// The grid position of the run's chunk `k` in `array` (its inner
/// dimensions whole: position 0).
fn grid_index(array: &Meta, chunks: &Chunks, k: usize) -> Vec<u64> {
    let mut index = chunks.grid_index(k);
    index.truncate(chunks.shape.len());
    index.resize(array.shape.len(), 0);
    index
}

/// Writes the axes as coordinate arrays and the group with `attributes`
/// (the resolved scene and the summary): the last step of a run.
pub fn finish(dir: &Path, scene: &Scene, attributes: serde_json::Value) -> Result<()> {
    let store = dir.join(STORE);
    for ax in &scene.axes {
        let n = ax.values.len() as u64;
        let folder = store.join(&ax.name);
        let names = [ax.name.clone()];
        write_metadata(&folder, &array_metadata(&[n], &[n.max(1)], "<f8", &names))?;
        let bytes: Vec<u8> = ax.values.iter().flat_map(|v| v.to_le_bytes()).collect();
        Meta::new(folder, vec![n], vec![n.max(1)], "<f8")
            .write(&[0], &bytes)
            .with_context(|| format!("writing {}/{}", store.display(), ax.name))?;
    }
    let attributes = match attributes {
        Value::Object(m) => Value::Object(m),
        other => json!({ "reeb": other }),
    };
    let group = json!({"zarr_format": 3, "node_type": "group", "attributes": attributes});
    write_metadata(&store, &group)
}

/// Writes array `name` of `shape` (dimensions `dims`) whole, in one chunk:
/// an array made after every chunk of the run (the attractors' labels).
pub fn write_whole(
    dir: &Path,
    name: &str,
    shape: &[u64],
    dims: &[String],
    descr: &str,
    bytes: &[u8],
) -> Result<()> {
    let folder = dir.join(STORE).join(name);
    let chunk: Vec<u64> = shape.iter().map(|s| (*s).max(1)).collect();
    write_metadata(&folder, &array_metadata(shape, &chunk, descr, dims))?;
    Meta::new(folder, shape.to_vec(), chunk, descr)
        .write(&vec![0; shape.len()], bytes)
        .with_context(|| format!("writing {}/{}/{name}", dir.display(), STORE))
}

/// The whole data of array `name` of the store in `dir`, as stored bytes.
pub fn read(dir: &Path, name: &str) -> Result<Vec<u8>> {
    let folder = dir.join(STORE).join(name);
    Meta::read(&folder)?
        .read_all()
        .with_context(|| format!("reading {}", folder.display()))
}
