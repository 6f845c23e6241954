//! The GPU context: the adapter chosen once (honouring `WGPU_BACKEND` and
//! `WGPU_ADAPTER_NAME`), its device and queue, and the pipeline cache.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use super::codegen::{ExpForm, Forms};
use super::tuning::Tuned;

/// Why the GPU backend cannot run.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter found (wgpu backends: {0}); {1}")]
    NoAdapter(String, String),
    #[error("WGPU_ADAPTER_NAME={0:?} matches none of the adapters: {1}")]
    NoMatchingAdapter(String, String),
    #[error(
        "--adapter {0}: there are {1} adapters (numbered from 0 as `reeb info` lists them: {2})"
    )]
    NoAdapterIndex(usize, usize, String),
    #[error("the adapter {0} has no SHADER_F64: run with --precision f32, or on the CPU backend")]
    NoF64(String),
    #[error("requesting the device failed: {0}")]
    Device(String),
    #[error("the generated kernel was rejected: {0}")]
    Shader(String),
    #[error(transparent)]
    Codegen(#[from] super::codegen::CodegenError),
    #[error("the GPU reported an error: {0}")]
    Runtime(String),
    #[error("{0}")]
    Setting(String),
}

/// What `reeb info` shows about an adapter.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
    pub shader_f64: bool,
    /// SHADER_INT64: the f64 kernels' `pow2` from the bits (faster on NVIDIA).
    pub shader_int64: bool,
    pub timestamps: bool,
    /// The f32 `exp` its devices use ([`exp_form`]).
    pub exp_f32: ExpForm,
    pub max_storage_buffer_binding_size: u64,
    pub max_buffer_size: u64,
    pub max_compute_workgroups_per_dimension: u32,
    pub max_storage_buffers_per_shader_stage: u32,
    /// Every feature the adapter offers, as wgpu names them.
    pub features: Vec<String>,
    /// Its key in the tuning cache (`tuning::adapter_key`).
    #[serde(skip)]
    pub tuning_key: String,
}

fn summary(a: &wgpu::Adapter) -> AdapterSummary {
    let info = a.get_info();
    let f = a.features();
    let l = a.limits();
    AdapterSummary {
        name: info.name.clone(),
        backend: format!("{:?}", info.backend),
        device_type: format!("{:?}", info.device_type),
        driver: format!("{} {}", info.driver, info.driver_info)
            .trim()
            .to_string(),
        shader_f64: f.contains(wgpu::Features::SHADER_F64),
        shader_int64: f.contains(wgpu::Features::SHADER_INT64),
        timestamps: f.contains(wgpu::Features::TIMESTAMP_QUERY),
        exp_f32: exp_form(&info).unwrap_or(default_exp(&info)),
        max_storage_buffer_binding_size: l.max_storage_buffer_binding_size,
        max_buffer_size: l.max_buffer_size,
        max_compute_workgroups_per_dimension: l.max_compute_workgroups_per_dimension,
        max_storage_buffers_per_shader_stage: l.max_storage_buffers_per_shader_stage,
        features: f.iter_names().map(|(name, _)| name.to_string()).collect(),
        tuning_key: super::tuning::adapter_key(&info),
    }
}

fn instance() -> wgpu::Instance {
    // Mesa's Vulkan loader prints an error per adapter when XDG_RUNTIME_DIR is
    // unset (headless machines, CI); it only needs a writable directory.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
    // Respects WGPU_BACKEND (and the other WGPU_* instance variables).
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

/// Every adapter wgpu can see (respecting `WGPU_BACKEND`).
pub fn list_adapters() -> Vec<AdapterSummary> {
    let inst = instance();
    pollster::block_on(inst.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(summary)
        .collect()
}

/// The adapters `--adapters all` spreads a run over: every hardware GPU
/// (not the GL twin of a Vulkan adapter), or, without one, the adapter
/// `--backend gpu` takes.
pub fn every_gpu() -> Result<Vec<usize>, GpuError> {
    let inst = instance();
    let adapters = pollster::block_on(inst.enumerate_adapters(wgpu::Backends::all()));
    let hardware: Vec<usize> = adapters
        .iter()
        .enumerate()
        .filter(|(_, a)| {
            let i = a.get_info();
            i.backend != wgpu::Backend::Gl && i.device_type != wgpu::DeviceType::Cpu
        })
        .map(|(k, _)| k)
        .collect();
    match hardware.is_empty() {
        true => Ok(vec![choose_adapter(&inst, None)?.0]),
        false => Ok(hardware),
    }
}

/// Picks the adapter: the one whose name contains `WGPU_ADAPTER_NAME` (case
/// insensitive) if that is set, else a discrete GPU, else an integrated or
/// virtual one, else a software one (lavapipe).
/// `index` (of `--adapter`, in the order `reeb info` lists) comes first.
fn choose_adapter(
    inst: &wgpu::Instance,
    index: Option<usize>,
) -> Result<(usize, wgpu::Adapter), GpuError> {
    check_backend_env()?;
    let adapters = pollster::block_on(inst.enumerate_adapters(wgpu::Backends::all()));
    let names = || {
        adapters
            .iter()
            .map(|a| a.get_info().name)
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(k) = index {
        return adapters
            .get(k)
            .map(|a| (k, a.clone()))
            .ok_or_else(|| GpuError::NoAdapterIndex(k, adapters.len(), names()));
    }
    if let Ok(want) = std::env::var("WGPU_ADAPTER_NAME") {
        let w = want.to_lowercase();
        return adapters
            .iter()
            .enumerate()
            .find(|(_, a)| a.get_info().name.to_lowercase().contains(&w))
            .map(|(k, a)| (k, a.clone()))
            .ok_or_else(|| GpuError::NoMatchingAdapter(want, names()));
    }
    let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    adapters
        .iter()
        .enumerate()
        .filter(|(_, a)| a.get_info().backend != wgpu::Backend::Gl || adapters.len() == 1)
        .min_by_key(|(_, a)| rank(a))
        .map(|(k, a)| (k, a.clone()))
        .ok_or_else(|| {
            GpuError::NoAdapter(
                format!(
                    "{:?}",
                    wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all())
                ),
                no_adapter_hint(),
            )
        })
}

/// `WGPU_BACKEND`, where set, names at least one backend (wgpu reads an
/// unknown or empty one as none, and no adapter would open).
fn check_backend_env() -> Result<(), GpuError> {
    match (std::env::var("WGPU_BACKEND"), wgpu::Backends::from_env()) {
        (Ok(set), Some(b)) if b.is_empty() => Err(GpuError::Setting(format!(
            "WGPU_BACKEND={set:?} names no wgpu backend: expected vulkan, metal, dx12 or gl (or a comma-separated list of them), or leave it unset for every one"
        ))),
        _ => Ok(()),
    }
}

/// What to do when no adapter opened: install a driver, or, where a Vulkan
/// driver's manifest is there already, find out why it did not load (seen
/// on an H200 machine: NVIDIA's manifest names libGLX_nvidia.so.0, which
/// needs the glvnd libraries that image lacked).
fn no_adapter_hint() -> String {
    let drivers = vulkan_manifests();
    if drivers.is_empty() {
        return "install a Vulkan driver, e.g. `apt-get install mesa-vulkan-drivers libvulkan1` for the software one".into();
    }
    format!(
        "Vulkan drivers are installed ({}) but none opened: `VK_LOADER_DEBUG=error,warn reeb info` says why; the loader libvulkan.so.1 must be there (`ldconfig -p | grep libvulkan`), and NVIDIA's driver also needs the glvnd libraries libGLdispatch.so.0 and libGLX.so.0 (Debian/Ubuntu: libglvnd0 libglx0)",
        drivers.join(", ")
    )
}

/// The Vulkan driver manifests the loader reads on Linux, as `file →
/// library`: those named by VK_DRIVER_FILES or VK_ICD_FILENAMES, else
/// those of the usual folders.
fn vulkan_manifests() -> Vec<String> {
    let named: Vec<std::path::PathBuf> = ["VK_DRIVER_FILES", "VK_ICD_FILENAMES"]
        .iter()
        .filter_map(std::env::var_os)
        .flat_map(|v| std::env::split_paths(&v).collect::<Vec<_>>())
        .collect();
    let files = match named.is_empty() {
        false => named,
        true => [
            "/etc/vulkan/icd.d",
            "/usr/local/share/vulkan/icd.d",
            "/usr/share/vulkan/icd.d",
        ]
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flatten()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect(),
    };
    files
        .iter()
        .filter(|f| f.is_file())
        .map(|f| {
            let library = std::fs::read_to_string(f)
                .ok()
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
                .and_then(|j| j["ICD"]["library_path"].as_str().map(String::from))
                .unwrap_or_else(|| "unreadable".into());
            format!("{} → {library}", f.display())
        })
        .collect()
}

/// Is the adapter a software rasteriser (lavapipe, llvmpipe, WARP)?
pub fn is_software(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}

/// The f32 `exp` of a device on this adapter: `REEB_GPU_EXP` (`exact` or
/// `hardware`) where set, else [`default_exp`].
pub fn exp_form(info: &wgpu::AdapterInfo) -> Result<ExpForm, GpuError> {
    match std::env::var(EXP_ENV).unwrap_or_default().as_str() {
        "" => Ok(default_exp(info)),
        "exact" => Ok(ExpForm::Exact),
        "hardware" => Ok(ExpForm::Hardware),
        other => Err(GpuError::Setting(format!(
            "REEB_GPU_EXP={other:?}: expected `exact` (reeb's polynomial, the CPU's function) or `hardware` (the adapter's exp2, a few ULP)"
        ))),
    }
}

/// Has the environment chosen the f32 `exp` ([`exp_form`])?
pub fn exp_chosen() -> bool {
    std::env::var(EXP_ENV).is_ok_and(|v| !v.is_empty())
}

const EXP_ENV: &str = "REEB_GPU_EXP";

/// The adapter's exp2 on a GPU (reeb's polynomial cost a third of van der
/// Pol S2's f32 rate on an H200, and a GPU's results already differ from
/// the CPU's by its contractions into fma); reeb's polynomial on a software
/// adapter, whose exp2 is not much use (lavapipe's: 63 ULP off near ±85).
pub fn default_exp(info: &wgpu::AdapterInfo) -> ExpForm {
    match is_software(info) {
        true => ExpForm::Exact,
        false => ExpForm::Hardware,
    }
}

/// A device ready to run reeb kernels.
pub struct GpuContext {
    /// The adapter's index in `reeb info`'s list.
    pub index: usize,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    pub shader_f64: bool,
    /// 64-bit integers in shaders: the f64 kernels' `pow2` from the bits.
    pub shader_int64: bool,
    /// The f32 kernels' `exp` ([`exp_form`]).
    pub exp_f32: ExpForm,
    pub timestamps: bool,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    pipelines: Mutex<HashMap<String, Arc<wgpu::ComputePipeline>>>,
    /// Wall nanoseconds spent compiling `pipelines` (the tuning probe
    /// leaves them out of its time budget).
    compile_nanos: AtomicU64,
    /// Launches tuned in this process, by plan shape (`backend/tune.rs`).
    tuned: Mutex<HashMap<String, Tuned>>,
    /// Errors the device reported outside an error scope.
    errors: Arc<Mutex<Vec<String>>>,
    /// Held by a run from its first submission of a chunk until that
    /// chunk's results are staged for reading: two runs on one device
    /// (chunks pipelined, `output/stream.rs`) take turns at the queue, and
    /// each reads its chunk back while the other integrates.
    queue_turn: Mutex<()>,
    /// Held while a launch is tuned: a second run waits for the first's
    /// probe instead of measuring beside it.
    probing: Mutex<()>,
    /// Buffers finished runs gave back, for the next run of the same sizes
    /// (a tuning probe runs one size tens of times; a new buffer is zeroed).
    pool: Mutex<VecDeque<wgpu::Buffer>>,
}

/// Most bytes of buffers [`GpuContext`] keeps for later runs.
pub const POOL_BYTES: u64 = 512 << 20;

impl GpuContext {
    /// Opens the adapter chosen by [`choose_adapter`] with its own limits, and
    /// SHADER_F64 and TIMESTAMP_QUERY where it has them.
    pub fn new() -> Result<GpuContext, GpuError> {
        GpuContext::on(None)
    }

    /// [`GpuContext::new`] on adapter `index` of `reeb info`'s list, if given.
    pub fn on(index: Option<usize>) -> Result<GpuContext, GpuError> {
        let inst = instance();
        let (index, adapter) = choose_adapter(&inst, index)?;
        let info = adapter.get_info();
        let exp_f32 = exp_form(&info)?;
        let features = adapter.features()
            & (wgpu::Features::SHADER_F64
                | wgpu::Features::SHADER_INT64
                | wgpu::Features::TIMESTAMP_QUERY);
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("reeb"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        let errors: Arc<Mutex<Vec<String>>> = Arc::default();
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut v) = sink.lock() {
                v.push(e.to_string());
            }
        }));
        let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("reeb kernel"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, rw),
                entry(2, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(3, rw),
                entry(4, rw),
                entry(5, rw),
                entry(6, rw),
                entry(7, rw),
                entry(8, wgpu::BufferBindingType::Uniform),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("reeb kernel"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        Ok(GpuContext {
            index,
            device,
            queue,
            shader_f64: features.contains(wgpu::Features::SHADER_F64),
            shader_int64: features.contains(wgpu::Features::SHADER_INT64),
            exp_f32,
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            info,
            limits,
            layout,
            pipeline_layout,
            pipelines: Mutex::default(),
            compile_nanos: AtomicU64::new(0),
            tuned: Mutex::default(),
            errors,
            queue_turn: Mutex::default(),
            probing: Mutex::default(),
            pool: Mutex::default(),
        })
    }

    /// One line naming the adapter (and its exp, where not reeb's).
    pub fn describe(&self) -> String {
        let exp = match self.exp_f32 {
            ExpForm::Exact => "",
            ExpForm::Hardware => "; f32 exp from the adapter's exp2",
        };
        format!(
            "{} ({:?}, {:?}{exp})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    /// How this device's kernels compute what it may compute its own way.
    pub fn forms(&self) -> Forms {
        Forms {
            int64: self.shader_int64,
            exp: self.exp_f32,
        }
    }

    pub fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// The launch tuned for plan shape `shape` in this process, if any.
    pub fn tuned(&self, shape: &str) -> Option<Tuned> {
        self.tuned.lock().ok()?.get(shape).cloned()
    }

    /// Keeps `tuned` for `shape` for the rest of this process.
    pub fn remember(&self, shape: &str, tuned: &Tuned) {
        if let Ok(mut m) = self.tuned.lock() {
            m.insert(shape.to_string(), tuned.clone());
        }
    }

    /// The compute pipeline of `source`'s `main` (validated already), with
    /// `layout` or the one its bindings imply; the device's complaints as
    /// an error.
    pub fn compile(
        &self,
        source: &str,
        layout: Option<&wgpu::PipelineLayout>,
        label: &str,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let pipeline = self
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(GpuError::Shader(e.to_string())),
            None => Ok(pipeline),
        }
    }

    /// The compute pipeline for `source`, compiled once per context (held
    /// locked meanwhile: two runs of one kernel compile it once).
    pub fn pipeline(&self, source: &str) -> Result<Arc<wgpu::ComputePipeline>, GpuError> {
        let mut pipelines = self
            .pipelines
            .lock()
            .map_err(|e| GpuError::Runtime(e.to_string()))?;
        if let Some(p) = pipelines.get(source) {
            return Ok(p.clone());
        }
        // Validate with naga first: its messages point into the source.
        let started = std::time::Instant::now();
        validate(source, true).map_err(GpuError::Shader)?;
        let p = Arc::new(self.compile(source, Some(&self.pipeline_layout), "reeb kernel")?);
        let nanos = started.elapsed().as_nanos().min(u64::MAX as u128) as u64;
        self.compile_nanos.fetch_add(nanos, Ordering::Relaxed);
        pipelines.insert(source.to_string(), p.clone());
        Ok(p)
    }

    /// Wall seconds this context has spent compiling kernels (naga's
    /// validation and the driver's compile: 0.14–0.19 s for a probe's
    /// candidates on a fresh H200, with a cold shader cache).
    pub fn compile_seconds(&self) -> f64 {
        self.compile_nanos.load(Ordering::Relaxed) as f64 * 1e-9
    }

    /// This run's turn at the queue: no other run submits work until the
    /// guard is dropped.
    pub fn queue_turn(&self) -> MutexGuard<'_, ()> {
        self.queue_turn
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// The right to tune a launch on this device, one run at a time.
    pub fn probing(&self) -> MutexGuard<'_, ()> {
        self.probing.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A buffer of `size` bytes and `usage`, one a finished run gave back
    /// where there is one (its contents are stale: every kernel writes what
    /// it reads but the status words, which each chunk clears).
    pub fn buffer(&self, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
        if let Ok(mut pool) = self.pool.lock() {
            if let Some(k) = pool
                .iter()
                .position(|b| b.size() == size && b.usage() == usage)
            {
                if let Some(b) = pool.remove(k) {
                    return b;
                }
            }
        }
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        })
    }

    /// Keeps `buf` (unmapped, and no longer used by a run) for a later
    /// [`GpuContext::buffer`], the oldest dropped beyond [`POOL_BYTES`] in all.
    pub fn give_back(&self, buf: wgpu::Buffer) {
        if buf.size() > POOL_BYTES {
            return;
        }
        let Ok(mut pool) = self.pool.lock() else {
            return;
        };
        pool.push_back(buf);
        while pool.iter().map(wgpu::Buffer::size).sum::<u64>() > POOL_BYTES {
            pool.pop_front();
        }
    }

    /// Errors the device reported since the last call.
    pub fn take_errors(&self) -> Vec<String> {
        self.errors
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default()
    }
}

/// Validates WGSL with naga (no GPU needed): parse, then validate with or
/// without the f64 capability. Returns naga's report on failure.
pub fn validate(source: &str, f64: bool) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(source).map_err(|e| e.emit_to_string(source))?;
    // 64-bit integers come with f64 (the f64 `pow2` on adapters with them).
    let caps = if f64 {
        naga::valid::Capabilities::FLOAT64 | naga::valid::Capabilities::SHADER_INT64
    } else {
        naga::valid::Capabilities::empty()
    };
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .map_err(|e| e.emit_to_string(source))?;
    Ok(())
}
