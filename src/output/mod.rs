//! What a run leaves on disk: `reeb run` (a scene through a backend into a
//! directory), the arrays, and the pictures drawn with the plotting module.

pub mod arrays;
pub mod attractors;
pub mod basin_pictures;
pub mod basins;
pub mod chunks;
pub mod directory;
pub mod doubts;
pub mod journal;
pub mod npy;
pub mod owned;
pub mod pictures;
pub mod plot;
pub mod progress;
pub mod references;
pub mod run;
pub mod slurm;
pub mod stream;
pub mod zarr;
