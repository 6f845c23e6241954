//! How a plan's kernel is launched on an adapter: the workgroup size, the
//! trajectories each invocation integrates, and the wall time a dispatch (a
//! window of steps) aims at. None of them changes a result's bits: every
//! trajectory runs the same operations whatever the launch
//! (`tests/suite/gpu.rs::every_launch_gives_the_same_bits`); they change the speed.
//! The probe that chooses them is `backend/tune.rs`; this file holds the
//! choice, its limits, the environment's overrides and the cache file.

use std::collections::BTreeMap;
use std::path::PathBuf;

/// Workgroup sizes the probe tries (each within the adapter's limits).
pub const WORKGROUPS: [u32; 3] = [64, 128, 256];
/// Trajectories per invocation the probe tries.
pub const PER_THREAD: [u32; 3] = [1, 2, 4];
/// Steps per finite test the probe tries beside 1 on a software adapter
/// (where the kernel has blocks: lavapipe's van der Pol blocks are 5 %
/// slower).
pub const FINITE_BLOCKS: [u32; 2] = [4, 8];
/// Steps per finite test on a hardware GPU, where the kernel has blocks,
/// not measured: a block only removes work (7 of every 8 tests), while
/// the probe's short runs are timed at partial clocks. On a fresh H200
/// they ranked f64's blocks backwards (1.67·10¹¹ trajectory-steps/s for a
/// test every step, 1.22 and 1.46·10¹¹ for blocks of 4 and 8) where whole
/// runs of 10⁷ trajectories give 4.37, 5.29 and 5.56·10¹¹ (f32: 8.67·10¹¹,
/// 1.43 and 1.59·10¹²); an earlier probe ran out of its second before the
/// blocks. `REEB_GPU_FINITE_BLOCK` overrides it.
pub const GPU_FINITE_BLOCK: u32 = 8;

/// A kernel launch.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Launch {
    /// Invocations per workgroup (`@workgroup_size`).
    pub workgroup: u32,
    /// Trajectories one invocation integrates, one after the other
    /// (strided by the dispatch's width, so neighbours stay coalesced).
    pub per_thread: u32,
    /// Wall seconds one dispatch aims at (the window adapts its steps).
    pub dispatch_seconds: f64,
    /// Most steps per dispatch (`REEB_GPU_WINDOW`), if fixed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<u64>,
    /// Steps per finite test in a kernel without observers (1: every
    /// step; `codegen::blocks`).
    #[serde(default = "every_step")]
    pub finite_block: u32,
}

fn every_step() -> u32 {
    1
}

impl Default for Launch {
    fn default() -> Launch {
        Launch {
            workgroup: 64,
            per_thread: 1,
            dispatch_seconds: 0.1,
            window: None,
            finite_block: 1,
        }
    }
}

impl Launch {
    /// Refuses a launch the adapter's limits forbid (it is never tried).
    pub fn check(&self, limits: &wgpu::Limits) -> Result<(), String> {
        self.knob_at_fault(limits).map_err(|(_, e)| e)
    }

    /// [`Self::check`], with the index into [`ENV`] of the knob at fault.
    fn knob_at_fault(&self, limits: &wgpu::Limits) -> Result<(), (usize, String)> {
        let most = limits
            .max_compute_invocations_per_workgroup
            .min(limits.max_compute_workgroup_size_x);
        if self.workgroup == 0 || self.workgroup > most {
            return Err((
                0,
                format!(
                    "a workgroup of {} invocations: this adapter allows 1 to {most}",
                    self.workgroup
                ),
            ));
        }
        if !(1..=64).contains(&self.per_thread) {
            return Err((
                1,
                format!("{} trajectories per invocation: 1 to 64", self.per_thread),
            ));
        }
        if !(0.001..=10.0).contains(&self.dispatch_seconds) {
            return Err((
                2,
                format!("{} s per dispatch: 0.001 to 10", self.dispatch_seconds),
            ));
        }
        if !(1..=8).contains(&self.finite_block) {
            return Err((
                4,
                format!("a finite test every {} steps: 1 to 8", self.finite_block),
            ));
        }
        Ok(())
    }

    /// One line: `workgroup 128, 2 per invocation, 0.05 s per dispatch`.
    pub fn describe(&self) -> String {
        let window = self.window.map_or(String::new(), |w| {
            format!(", at most {w} steps per dispatch")
        });
        let block = match self.finite_block {
            1 => String::new(),
            b => format!(", finite test every {b} steps"),
        };
        format!(
            "workgroup {}, {} per invocation, {} s per dispatch{window}{block}",
            self.workgroup, self.per_thread, self.dispatch_seconds
        )
    }
}

/// What the environment fixes, each overriding the probe's choice.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overrides {
    pub workgroup: Option<u32>,
    pub per_thread: Option<u32>,
    pub dispatch_seconds: Option<f64>,
    pub window: Option<u64>,
    pub finite_block: Option<u32>,
}

/// The environment variables of [`Overrides`], as the README names them.
pub const ENV: [&str; 5] = [
    "REEB_GPU_WORKGROUP",
    "REEB_GPU_PER_THREAD",
    "REEB_GPU_DISPATCH_SECONDS",
    "REEB_GPU_WINDOW",
    "REEB_GPU_FINITE_BLOCK",
];

impl Overrides {
    /// The overrides the environment sets; an error names the variable.
    pub fn from_env() -> Result<Overrides, String> {
        fn var<T: std::str::FromStr>(name: &str) -> Result<Option<T>, String> {
            match std::env::var(name) {
                Err(_) => Ok(None),
                Ok(v) if v.trim().is_empty() => Ok(None),
                Ok(v) => v
                    .trim()
                    .parse()
                    .map(Some)
                    .map_err(|_| format!("{name}={v:?} is not a number")),
            }
        }
        let o = Overrides {
            workgroup: var(ENV[0])?,
            per_thread: var(ENV[1])?,
            dispatch_seconds: var(ENV[2])?,
            window: var(ENV[3])?,
            finite_block: var(ENV[4])?,
        };
        if o.window == Some(0) {
            return Err(format!("{}=0: at least 1 step per dispatch", ENV[3]));
        }
        Ok(o)
    }

    /// The variables set, as `REEB_GPU_WORKGROUP=128, …`.
    pub fn describe(&self) -> String {
        let values = [
            self.workgroup.map(|v| v.to_string()),
            self.per_thread.map(|v| v.to_string()),
            self.dispatch_seconds.map(|v| v.to_string()),
            self.window.map(|v| v.to_string()),
            self.finite_block.map(|v| v.to_string()),
        ];
        let set: Vec<String> = ENV
            .iter()
            .zip(values)
            .filter_map(|(name, v)| v.map(|v| format!("{name}={v}")))
            .collect();
        set.join(", ")
    }

    /// Does the environment fix every knob the probe would choose?
    pub fn complete(&self) -> bool {
        self.workgroup.is_some() && self.per_thread.is_some() && self.dispatch_seconds.is_some()
    }

    /// `launch` with the overrides applied, checked against the adapter's limits.
    pub fn apply(&self, launch: Launch, limits: &wgpu::Limits) -> Result<Launch, String> {
        let l = Launch {
            workgroup: self.workgroup.unwrap_or(launch.workgroup),
            per_thread: self.per_thread.unwrap_or(launch.per_thread),
            dispatch_seconds: self.dispatch_seconds.unwrap_or(launch.dispatch_seconds),
            window: self.window.or(launch.window),
            finite_block: self.finite_block.unwrap_or(launch.finite_block),
        };
        l.knob_at_fault(limits).map_err(|(knob, e)| {
            let set = [
                self.workgroup.is_some(),
                self.per_thread.is_some(),
                self.dispatch_seconds.is_some(),
                self.window.is_some(),
                self.finite_block.is_some(),
            ];
            match set[knob] {
                true => format!("{}: {e}", ENV[knob]),
                false => format!("{e} (the tuned launch with {})", self.describe()),
            }
        })?;
        Ok(l)
    }
}

/// A probe's result for one adapter and plan shape.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Tuned {
    pub launch: Launch,
    /// Trajectory-steps per second of the probe's plan with `launch`.
    pub gpu_rate: f64,
    /// The CPU backend's, on the same plan (all threads).
    pub cpu_rate: f64,
    /// Trajectories of the probe (the smaller of the plan's and the probe's).
    pub trajectories: u64,
    /// Wall seconds the probe took.
    pub probe_seconds: f64,
    /// Of which compiling the candidates' kernels (outside the budget of
    /// `tune::PROBE_SECONDS`; the driver caches them for the next time).
    #[serde(default)]
    pub compile_seconds: f64,
    /// Wall seconds per trajectory of a GPU run beyond its kernel (tables,
    /// buffers, dispatches, read-back), measured on the probe's plan.
    #[serde(default)]
    pub gpu_host_per_trajectory: f64,
    /// The CPU backend's beyond its integration (its set-up), likewise.
    #[serde(default)]
    pub cpu_host_per_trajectory: f64,
}

impl Tuned {
    /// Seconds a plan of `n` trajectories × `steps` steps would take on the
    /// GPU and on the CPU, each its integration and its own host work
    /// (writing and pictures, the same on either, aside).
    pub fn whole_run_seconds(&self, n: u64, steps: u64) -> (f64, f64) {
        let (n, work) = (n as f64, (n * steps) as f64);
        (
            work / self.gpu_rate + n * self.gpu_host_per_trajectory,
            work / self.cpu_rate + n * self.cpu_host_per_trajectory,
        )
    }
}

/// The cache: probes by adapter (name, backend, driver) and plan shape.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Cache {
    pub reeb_version: String,
    /// The probe that measured it ([`PROBE`]; 0 in files from before).
    #[serde(default)]
    pub probe: u32,
    pub tuned: BTreeMap<String, BTreeMap<String, Tuned>>,
}

/// The probe's generation: a cache from an earlier one is measured again
/// (2: blocks of 4 and 8 steps tried first; 3: blocks of 8 taken on a
/// hardware GPU, not measured; 4: the host's seconds per trajectory).
pub const PROBE: u32 = 4;

/// The file name of the cache in reeb's cache directory.
pub const CACHE_FILE: &str = "gpu-tuning.json";

/// `$XDG_CACHE_HOME/reeb/`, or `~/.cache/reeb/`.
pub fn cache_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("reeb"))
}

/// The key of an adapter: what decides its speed and its bits.
pub fn adapter_key(i: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {} {})",
        i.name, i.backend, i.driver, i.driver_info
    )
}

impl Cache {
    /// The cache file's contents; a missing, unreadable, corrupt file or
    /// one of another reeb version or probe is an empty cache (re-measured).
    pub fn load() -> Cache {
        let empty = Cache {
            reeb_version: env!("CARGO_PKG_VERSION").into(),
            probe: PROBE,
            ..Default::default()
        };
        let Some(path) = cache_dir().map(|d| d.join(CACHE_FILE)) else {
            return empty;
        };
        std::fs::read_to_string(path)
            .ok()
            .and_then(|s| serde_json::from_str::<Cache>(&s).ok())
            .filter(|c| c.reeb_version == env!("CARGO_PKG_VERSION") && c.probe == PROBE)
            .unwrap_or(empty)
    }

    pub fn get(&self, adapter: &str, shape: &str) -> Option<&Tuned> {
        self.tuned.get(adapter)?.get(shape)
    }

    /// Adds `tuned` to the file (read again, so that other processes'
    /// entries stay), written whole under another name and renamed.
    pub fn store(adapter: &str, shape: &str, tuned: &Tuned) -> std::io::Result<PathBuf> {
        let dir = cache_dir().ok_or_else(|| {
            std::io::Error::other("no cache directory (set XDG_CACHE_HOME or HOME)")
        })?;
        std::fs::create_dir_all(&dir)?;
        let mut cache = Cache::load();
        cache
            .tuned
            .entry(adapter.to_string())
            .or_default()
            .insert(shape.to_string(), tuned.clone());
        let path = dir.join(CACHE_FILE);
        let tmp = dir.join(format!("{CACHE_FILE}.{}.partial", std::process::id()));
        let text = serde_json::to_string_pretty(&cache).map_err(std::io::Error::other)?;
        // Never leave the private copy behind (a folder or a read-only
        // file in the cache's place makes the rename fail at every run).
        let written = std::fs::write(&tmp, text + "\n").and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(std::io::Error::new(
                e.kind(),
                format!("{}: {e}", path.display()),
            ));
        }
        Ok(path)
    }
}
