//! Where a run's time goes, phase by phase: what `summary.json`'s `timing`
//! reports. The backends measure the phases of an integration; the outputs
//! add writing, pictures and the whole wall.

use std::time::Instant;

/// Seconds spent in each phase of a run (or of one chunk of it).
#[derive(Debug, Default, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Phases {
    /// Tables, buffers, programs and result arrays made before the first
    /// step; at the run's level also the scene's checks, the plans, the
    /// backend's choice and the output directory.
    pub setup: f64,
    /// Shaders generated and compiled (the CPU's kernels are compiled
    /// ahead of time: 0 there).
    pub compile: f64,
    /// The steps and their observers: GPU timestamps where the adapter has
    /// them, else the wall clock.
    pub integration: f64,
    /// Results from the device into the run's arrays (0 on the CPU, whose
    /// blocks write them as they finish, inside the integration).
    pub read_back: f64,
    /// The arrays as bytes into their files and each finished chunk's
    /// marker (the files are synced once, while the pictures are drawn).
    pub writing: f64,
    /// The finished arrays read back, their doubts and the pictures.
    pub pictures: f64,
}

impl Phases {
    /// Every phase of `self` and `other` added.
    pub fn plus(self, other: Phases) -> Phases {
        Phases {
            setup: self.setup + other.setup,
            compile: self.compile + other.compile,
            integration: self.integration + other.integration,
            read_back: self.read_back + other.read_back,
            writing: self.writing + other.writing,
            pictures: self.pictures + other.pictures,
        }
    }

    /// The phases as `(name, seconds)`, in the order a run goes through them.
    pub fn named(&self) -> [(&'static str, f64); 6] {
        [
            ("setup", self.setup),
            ("compile", self.compile),
            ("integration", self.integration),
            ("read_back", self.read_back),
            ("writing", self.writing),
            ("pictures", self.pictures),
        ]
    }
}

/// Seconds since `since`, and `since` moved to now: the phases of a run
/// are measured one after the other from one clock.
pub fn lap(since: &mut Instant) -> f64 {
    let now = Instant::now();
    let s = now.duration_since(*since).as_secs_f64();
    *since = now;
    s
}
