//! reeb's integration tests, one test binary (one link of the library and
//! its dependencies instead of one per file): each module is a concern,
//! through the library or through the `reeb` command line
//! (`CARGO_BIN_EXE_reeb`). `common` holds what several share.

mod common;

mod alignment;
mod attractors;
mod batch_logs;
mod checkpoint;
mod cli;
mod cli_fuzz;
mod cpu;
mod disk_full;
mod docs;
mod doctor;
mod formula_limits;
mod formula_models;
mod gpu;
mod layers;
mod math;
mod observers;
mod on_disk;
mod oracles;
mod pictures;
mod recorded;
mod reports;
mod safety;
mod scene_fuzz;
mod scenes;
mod scheme_props;
mod shaders;
mod sizes;
mod slurm;
mod slurm_scripts;
mod stream;
mod surprises;
mod tangent;
mod trust;
mod tuning;
mod zarr;
