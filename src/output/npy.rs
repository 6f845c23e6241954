//! `.npy` files written in slabs: the header for the final shape first and
//! the file sized to it, then each chunk's contiguous rows in place, in any
//! order, from any number of processes (each writes only its own rows).

use std::fs::{File, OpenOptions};
use std::io::Read;
use std::os::unix::fs::FileExt;
use std::path::Path;

use anyhow::{bail, Context, Result};

/// An element type of the arrays reeb writes whole ([`crate::output::arrays::write_npy`]).
pub trait Element: bytemuck::Pod {
    /// Its numpy type, little-endian.
    const DESCR: &'static str;
}

impl Element for f64 {
    const DESCR: &'static str = "<f8";
}

impl Element for f32 {
    const DESCR: &'static str = "<f4";
}

impl Element for i32 {
    const DESCR: &'static str = "<i4";
}

/// The `.npy` (version 1.0) header of a C-order array: magic, version,
/// length, and the dict padded with spaces to a multiple of 64 bytes.
pub fn header(descr: &str, shape: &[u64]) -> Vec<u8> {
    let dims = match shape {
        [n] => format!("({n},)"),
        _ => {
            let d: Vec<String> = shape.iter().map(u64::to_string).collect();
            format!("({})", d.join(", "))
        }
    };
    header_of(descr, &dims)
}

/// [`header`] with every dimension followed by `, ` (`(5, )`), as the
/// arrays written whole ([`crate::output::arrays::write_npy`]) have always
/// had it: their files stay byte for byte what they were.
pub fn whole_header(descr: &str, shape: &[u64]) -> Vec<u8> {
    let dims: String = shape.iter().map(|n| format!("{n}, ")).collect();
    header_of(descr, &format!("({dims})"))
}

/// The header around a shape written out (`dims`).
fn header_of(descr: &str, dims: &str) -> Vec<u8> {
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {dims}, }}");
    let unpadded = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((dict.len() as u16).to_le_bytes());
    out.extend(dict.as_bytes());
    out
}

/// An `.npy` file of the final shape whose rows (the leading dimension's
/// entries flattened over the scene's axes) are written in slabs.
pub struct Slabs {
    file: File,
    header: u64,
    row_bytes: u64,
}

impl Slabs {
    /// Opens `path`, creating it with its header and full size if absent;
    /// its data is `rows` rows (the scene's trajectories) of equal size.
    /// Only the process that creates it writes the header; the others find
    /// it (or its size) already there and never write below it.
    pub fn open(path: &Path, descr: &str, shape: &[u64], rows: u64) -> Result<Slabs> {
        let head = header(descr, shape);
        let data = shape.iter().product::<u64>() * item_size(descr)?;
        let row_bytes = data / rows.max(1);
        let len = head.len() as u64 + data;
        let made = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(path);
        let file = match made {
            Ok(f) => {
                f.write_all_at(&head, 0)
                    .with_context(|| format!("writing {}", path.display()))?;
                f
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let f = OpenOptions::new()
                    .read(true)
                    .write(true)
                    .open(path)
                    .with_context(|| format!("opening {}", path.display()))?;
                check_header(&f, path, &head)?;
                f
            }
            Err(e) => return Err(e).with_context(|| format!("creating {}", path.display())),
        };
        // Extending to the final size is the same for every process; it
        // never cuts rows another process wrote.
        if file.metadata()?.len() < len {
            file.set_len(len)
                .with_context(|| format!("sizing {}", path.display()))?;
        }
        Ok(Slabs {
            file,
            header: head.len() as u64,
            row_bytes,
        })
    }

    /// Writes `bytes` (whole rows) from row `first` on.
    pub fn write_rows(&self, first: u64, bytes: &[u8], path: &Path) -> Result<()> {
        self.file
            .write_all_at(bytes, self.header + first * self.row_bytes)
            .with_context(|| format!("writing {}", path.display()))
    }

    /// Reads `count` rows from row `first` on (to check what was written).
    pub fn read_rows(&self, first: u64, count: u64, path: &Path) -> Result<Vec<u8>> {
        let mut out = vec![0u8; (count * self.row_bytes) as usize];
        self.file
            .read_exact_at(&mut out, self.header + first * self.row_bytes)
            .with_context(|| format!("reading {}", path.display()))?;
        Ok(out)
    }
}

/// Refuses a file whose header is not the one this run writes (a store of
/// another scene or shape).
fn check_header(f: &File, path: &Path, want: &[u8]) -> Result<()> {
    let mut have = vec![0u8; want.len()];
    // A file whose creator has not yet written its header reads as zeros:
    // wait for it briefly.
    for _ in 0..50 {
        let n = f.read_at(&mut have, 0).unwrap_or(0);
        if n == want.len() && have.iter().any(|b| *b != 0) {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    if have != want {
        bail!(
            "{} holds an array of another shape or type than this run writes; it belongs to another scene: remove the output or choose another --out",
            path.display()
        );
    }
    Ok(())
}

/// Bytes per element of a numpy type string (`<f8`, `|u1`, …).
pub fn item_size(descr: &str) -> Result<u64> {
    descr
        .get(2..)
        .and_then(|n| n.parse().ok())
        .with_context(|| format!("numpy type {descr}"))
}

/// Reads the raw little-endian data of an `.npy` file written by [`Slabs`]
/// (or [`crate::output::arrays::write_npy`]): its rows `first..first + rows` of `row_bytes` each.
pub fn read_rows(path: &Path, first: u64, rows: u64, row_bytes: u64) -> Result<Vec<u8>> {
    let mut out = vec![0u8; (rows * row_bytes) as usize];
    read_rows_into(path, first * row_bytes, &mut out)?;
    Ok(out)
}

/// Fills `out` from the data of the `.npy` file at `path`, from byte
/// `offset` of its data on (rows of the right size: no copy between).
pub fn read_rows_into(path: &Path, offset: u64, out: &mut [u8]) -> Result<()> {
    let mut f = File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let mut pre = [0u8; 10];
    f.read_exact(&mut pre)
        .with_context(|| format!("reading {}", path.display()))?;
    if &pre[..6] != b"\x93NUMPY" {
        bail!("{} is not an .npy file", path.display());
    }
    let head = 10 + u16::from_le_bytes([pre[8], pre[9]]) as u64;
    f.read_exact_at(out, head + offset)
        .with_context(|| format!("reading {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_are_what_numpy_writes() {
        let h = header("<f8", &[3, 4]);
        assert_eq!(h.len() % 64, 0);
        let text = std::str::from_utf8(&h[10..]).unwrap();
        assert!(text.starts_with("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }"));
        assert!(text.ends_with(" \n"));
        assert!(std::str::from_utf8(&header("|u1", &[7])[10..])
            .unwrap()
            .contains("'shape': (7,)"));
        assert!(std::str::from_utf8(&header("<f4", &[])[10..])
            .unwrap()
            .contains("'shape': ()"));
    }
}
