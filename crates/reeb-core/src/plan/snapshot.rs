//! A mid-run snapshot of one plan's integration (`--checkpoint-every`): a
//! header saying which run and engine it belongs to, the observations so
//! far, then what the backend needs to continue (its body). Written and read
//! as a stream, so a snapshot of a chunk of 1 GiB never takes a second GiB
//! of memory. Continuing from a snapshot gives outputs bitwise identical to
//! a run that was never interrupted.

use std::io::{self, Read, Write};

use crate::num::precision::Real;
use crate::plan::observations::{Col, ColMut, Observations};
use crate::plan::Plan;

const MAGIC: &[u8; 8] = b"REEBSNAP";
/// 2: observer slots in `plan/slots.rs` order (0.3); 3: SALI's and GALI's
/// columns among the observations'; 4: the attractor detector's columns.
const VERSION: u32 = 4;

/// Which integration a snapshot continues, and how far it had come.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// The engine that took it (`Engine::fingerprint`): a snapshot continues
    /// only on the same one, which computes the same bits.
    pub engine: String,
    pub precision: String,
    /// The plan's rows (`first..first + n`) and steps.
    pub first: u64,
    pub n: u64,
    pub steps: u64,
    /// Integration seconds before the snapshot.
    pub seconds: f64,
    /// Trajectory-steps done before the snapshot (the progress bar's).
    pub traj_steps: u64,
}

impl Header {
    /// The header a snapshot of `plan` on `engine` has (seconds and
    /// trajectory-steps zero).
    pub fn of<R: Real>(plan: &Plan, engine: String) -> Header {
        Header {
            engine,
            precision: R::NAME.into(),
            first: plan.first as u64,
            n: plan.n as u64,
            steps: plan.steps,
            seconds: 0.0,
            traj_steps: 0,
        }
    }

    /// Whether a snapshot with this header continues the integration
    /// `expected` describes; if not, why, as a user reads it.
    pub fn continues(&self, expected: &Header) -> Result<(), String> {
        let mut why = vec![];
        if self.engine != expected.engine {
            why.push(format!(
                "taken on {}, this run is on {}",
                self.engine, expected.engine
            ));
        }
        if self.precision != expected.precision {
            why.push(format!(
                "in {}, this run is in {}",
                self.precision, expected.precision
            ));
        }
        let span = |h: &Header| (h.first, h.n, h.steps);
        if span(self) != span(expected) {
            why.push(format!(
                "of trajectories {}..{} over {} steps, this run integrates {}..{} over {}",
                self.first,
                self.first + self.n,
                self.steps,
                expected.first,
                expected.first + expected.n,
                expected.steps
            ));
        }
        match why.is_empty() {
            true => Ok(()),
            false => Err(why.join("; ")),
        }
    }

    pub fn write(&self, w: &mut dyn Write) -> io::Result<()> {
        w.write_all(MAGIC)?;
        put(w, &[VERSION])?;
        put_str(w, &self.engine)?;
        put_str(w, &self.precision)?;
        put(w, &[self.first, self.n, self.steps, self.traj_steps])?;
        put(w, &[self.seconds])
    }

    pub fn read(r: &mut dyn Read) -> io::Result<Header> {
        let mut magic = [0u8; 8];
        r.read_exact(&mut magic)?;
        if &magic != MAGIC {
            return Err(invalid("not a reeb snapshot"));
        }
        let version: u32 = get_one(r)?;
        if version != VERSION {
            return Err(invalid(&format!(
                "a snapshot of version {version}, this reeb reads {VERSION}"
            )));
        }
        let engine = get_str(r)?;
        let precision = get_str(r)?;
        let [first, n, steps, traj_steps]: [u64; 4] = get_array(r)?;
        let seconds = get_one(r)?;
        Ok(Header {
            engine,
            precision,
            first,
            n,
            steps,
            seconds,
            traj_steps,
        })
    }
}

/// The columns of `obs` in their declared order, each with its length.
pub fn write_observations<R: Real>(w: &mut dyn Write, obs: &Observations<R>) -> io::Result<()> {
    for (_, column) in obs.columns() {
        match column {
            Col::Real(v) => put_slice(w, v)?,
            Col::Count(v) => put_slice(w, v)?,
            Col::Int(v) => put_slice(w, v)?,
        }
    }
    Ok(())
}

/// Reads what [`write_observations`] wrote into `obs`, which is sized for
/// the same plan (a length that differs is an error).
pub fn read_observations<R: Real>(r: &mut dyn Read, obs: &mut Observations<R>) -> io::Result<()> {
    for (_, column) in obs.columns_mut() {
        match column {
            ColMut::Real(v) => get_into(r, v)?,
            ColMut::Count(v) => get_into(r, v)?,
            ColMut::Int(v) => get_into(r, v)?,
        }
    }
    Ok(())
}

/// Writes `v` (plain values) as they lie in memory.
pub fn put<T: bytemuck::Pod>(w: &mut dyn Write, v: &[T]) -> io::Result<()> {
    w.write_all(bytemuck::cast_slice(v))
}

/// Writes `v` with its length first.
pub fn put_slice<T: bytemuck::Pod>(w: &mut dyn Write, v: &[T]) -> io::Result<()> {
    put(w, &[v.len() as u64])?;
    put(w, v)
}

fn put_str(w: &mut dyn Write, s: &str) -> io::Result<()> {
    put_slice(w, s.as_bytes())
}

/// Reads `v.len()` values into `v`.
pub fn get<T: bytemuck::Pod>(r: &mut dyn Read, v: &mut [T]) -> io::Result<()> {
    r.read_exact(bytemuck::cast_slice_mut(v))
}

pub fn get_one<T: bytemuck::Pod>(r: &mut dyn Read) -> io::Result<T> {
    let [x] = get_array(r)?;
    Ok(x)
}

pub fn get_array<T: bytemuck::Pod, const N: usize>(r: &mut dyn Read) -> io::Result<[T; N]> {
    let mut a = [T::zeroed(); N];
    get(r, &mut a)?;
    Ok(a)
}

/// Reads what [`put_slice`] wrote into `v`, whose length it must have.
pub fn get_into<T: bytemuck::Pod>(r: &mut dyn Read, v: &mut [T]) -> io::Result<()> {
    let len: u64 = get_one(r)?;
    if len != v.len() as u64 {
        return Err(invalid(&format!(
            "an array of {len} values where {} were expected",
            v.len()
        )));
    }
    get(r, v)
}

/// Reads what [`put_slice`] wrote, at most `limit` values.
pub fn get_vec<T: bytemuck::Pod>(r: &mut dyn Read, limit: usize) -> io::Result<Vec<T>> {
    let len: u64 = get_one(r)?;
    if len > limit as u64 {
        return Err(invalid(&format!(
            "an array of {len} values, more than the {limit} possible"
        )));
    }
    let mut v = vec![T::zeroed(); len as usize];
    get(r, &mut v)?;
    Ok(v)
}

fn get_str(r: &mut dyn Read) -> io::Result<String> {
    String::from_utf8(get_vec(r, 4096)?).map_err(|_| invalid("a name that is not UTF-8"))
}

pub fn invalid(why: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, why.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_header_reads_back_and_says_what_differs() {
        let h = Header {
            engine: "cpu v3".into(),
            precision: "f64".into(),
            first: 64,
            n: 128,
            steps: 1000,
            seconds: 1.5,
            traj_steps: 4096,
        };
        let mut bytes = vec![];
        h.write(&mut bytes).unwrap();
        assert_eq!(Header::read(&mut bytes.as_slice()).unwrap(), h);
        assert!(h.continues(&h).is_ok());
        let other = Header {
            engine: "gpu X".into(),
            steps: 2000,
            ..h.clone()
        };
        let why = h.continues(&other).unwrap_err();
        assert!(
            why.contains("taken on cpu v3, this run is on gpu X"),
            "{why}"
        );
        assert!(why.contains("over 1000 steps"), "{why}");
        assert!(Header::read(&mut &b"REEBSNAX...."[..]).is_err());
    }

    #[test]
    fn a_length_that_differs_is_refused() {
        let mut bytes = vec![];
        put_slice(&mut bytes, &[1.0f64, 2.0, 3.0]).unwrap();
        let mut two = [0.0f64; 2];
        assert!(get_into(&mut bytes.as_slice(), &mut two).is_err());
        let mut three = [0.0f64; 3];
        get_into(&mut bytes.as_slice(), &mut three).unwrap();
        assert_eq!(three, [1.0, 2.0, 3.0]);
        assert!(get_vec::<f64>(&mut bytes.as_slice(), 2).is_err());
    }
}
