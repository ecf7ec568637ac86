//! ONNX Runtime, loaded at run time from the model cache, and one model session.

use crate::error::ModelError;
use crate::store::ModelStore;
pub use aeris_schemas::accelerator::{Accelerator, AcceleratorKind};
use ort::environment::Environment;
use ort::ep;
use ort::session::Session;
use ort::session::builder::GraphOptimizationLevel;
use ort::value::TensorRef;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Where the provisioned ONNX Runtime library lies inside the cache.
pub const RUNTIME_LIBRARY: &str = "onnxruntime/libonnxruntime.so";

/// Environment variable naming an ONNX Runtime library of the user's own instead of the
/// provisioned one (JetPack ships its build with the CUDA and TensorRT providers):
/// `AERIS_ONNXRUNTIME=/usr/lib/aarch64-linux-gnu/libonnxruntime.so`. Its version must be
/// one `ort` supports (1.[`ort::MINOR_VERSION`] or newer), which loading checks.
pub const RUNTIME_ENV: &str = "AERIS_ONNXRUNTIME";

static ENVIRONMENT: OnceLock<Result<Environment, String>> = OnceLock::new();

/// The ONNX Runtime library a process loads: `$AERIS_ONNXRUNTIME` if set, else the one in
/// `store`.
pub fn runtime_library(store: &ModelStore) -> PathBuf {
    match std::env::var_os(RUNTIME_ENV).filter(|p| !p.is_empty()) {
        Some(p) => PathBuf::from(p),
        None => store.root().join(RUNTIME_LIBRARY),
    }
}

/// The process's ONNX Runtime environment, loading the library ([`runtime_library`]) on
/// first use.
///
/// A process loads one ONNX Runtime; later calls return the same environment.
pub fn environment(store: &ModelStore) -> Result<&'static Environment, ModelError> {
    let lib = runtime_library(store);
    let own = std::env::var_os(RUNTIME_ENV).is_some_and(|p| !p.is_empty());
    if ENVIRONMENT.get().is_none() {
        if own {
            // the user's library has no manifest entry; it must at least be there
            if !lib.is_file() {
                return Err(ModelError::OwnRuntime {
                    reason: format!("{} does not exist", lib.display()),
                    path: lib,
                });
            }
        } else {
            // verify before dlopen: a corrupt library would crash the process, not fail;
            // the store's error names the file and the command that fixes it
            store.verified(RUNTIME_LIBRARY)?;
        }
    }
    let env = ENVIRONMENT.get_or_init(|| {
        ort::init_from(&lib)
            .map_err(|e| e.to_string())?
            .with_name("aeris")
            .build()
            .map_err(|e| e.to_string())
    });
    env.as_ref().map_err(|reason| {
        let (path, reason) = (lib, reason.clone());
        if own {
            ModelError::OwnRuntime { path, reason }
        } else {
            ModelError::Runtime { path, reason }
        }
    })
}

/// What kind of hardware an execution provider device is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    /// A CPU.
    Cpu,
    /// A GPU.
    Gpu,
    /// A neural processing unit.
    Npu,
    /// An FPGA.
    Fpga,
}

impl DeviceKind {
    /// Lower-case name (`cpu`, `gpu`, `npu`, `fpga`).
    pub fn as_str(&self) -> &'static str {
        match self {
            DeviceKind::Cpu => "cpu",
            DeviceKind::Gpu => "gpu",
            DeviceKind::Npu => "npu",
            DeviceKind::Fpga => "fpga",
        }
    }
}

/// One device an execution provider of the loaded runtime offers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProviderDevice {
    /// The execution provider (`CPUExecutionProvider`, `CUDAExecutionProvider`, ...).
    pub provider: String,
    /// The hardware.
    pub kind: DeviceKind,
    /// Its vendor as ONNX Runtime reports it.
    pub vendor: String,
    /// Its device id.
    pub device_id: u32,
}

/// What the loaded ONNX Runtime can run models on.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ProviderReport {
    /// Execution providers compiled into the library, in ONNX Runtime's priority order
    /// (`GetAvailableProviders`: compiled in, not necessarily usable on this machine).
    pub providers: Vec<String>,
    /// Devices the providers found on this machine (`GetEpDevices`).
    pub devices: Vec<ProviderDevice>,
}

/// Ask the ONNX Runtime in `store` which execution providers it has and which devices they
/// found. Loads the runtime (once per process) if no model did yet.
pub fn execution_providers(store: &ModelStore) -> Result<ProviderReport, ModelError> {
    let env = environment(store)?;
    let runtime = |reason: String| ModelError::Runtime {
        path: runtime_library(store),
        reason,
    };
    let api = ort::api();
    let mut names: *mut *mut core::ffi::c_char = std::ptr::null_mut();
    let mut count: core::ffi::c_int = 0;
    // SAFETY: the runtime is loaded (`environment` succeeded); both out-pointers are valid
    // for writes. On success the runtime owns the array until ReleaseAvailableProviders.
    let status = unsafe { (api.GetAvailableProviders)(&mut names, &mut count) };
    if !status.0.is_null() {
        // SAFETY: a non-null status from the call above, released once.
        unsafe { (api.ReleaseStatus)(status.0) };
        return Err(runtime("GetAvailableProviders failed".into()));
    }
    let mut providers = Vec::new();
    if !names.is_null() {
        for i in 0..usize::try_from(count).unwrap_or(0) {
            // SAFETY: `names` holds `count` NUL-terminated strings owned by the runtime.
            let name = unsafe { std::ffi::CStr::from_ptr(*names.add(i)) };
            providers.push(name.to_string_lossy().into_owned());
        }
        // SAFETY: the array and count the runtime gave above, released once.
        let status = unsafe { (api.ReleaseAvailableProviders)(names, count) };
        if !status.0.is_null() {
            // SAFETY: as above.
            unsafe { (api.ReleaseStatus)(status.0) };
        }
    }
    let devices = env
        .devices()
        .filter_map(|d| {
            let hw = d.hardware_device();
            Some(ProviderDevice {
                provider: d.ep().ok()?.to_string(),
                kind: match hw.ty() {
                    ort::memory::DeviceType::CPU => DeviceKind::Cpu,
                    ort::memory::DeviceType::GPU => DeviceKind::Gpu,
                    ort::memory::DeviceType::NPU => DeviceKind::Npu,
                    ort::memory::DeviceType::FPGA => DeviceKind::Fpga,
                },
                vendor: hw.vendor().unwrap_or("unknown").to_string(),
                device_id: hw.id(),
            })
        })
        .collect();
    Ok(ProviderReport { providers, devices })
}

/// One ONNX model session and the name it is reported under.
pub struct OnnxModel {
    session: Session,
    name: String,
    path: PathBuf,
}

impl std::fmt::Debug for OnnxModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxModel")
            .field("name", &self.name)
            .field("path", &self.path)
            .finish()
    }
}

/// Where and how a model session runs.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SessionOptions {
    /// Intra-op threads on the CPU (0 = ONNX Runtime's default).
    pub threads: usize,
    /// The accelerator to run on (`None`: the CPU).
    pub accelerator: Option<Accelerator>,
}

impl SessionOptions {
    /// On the CPU with `threads` intra-op threads.
    pub fn cpu(threads: usize) -> Self {
        SessionOptions {
            threads,
            accelerator: None,
        }
    }
}

/// Check that the loaded ONNX Runtime offers `accelerator`'s execution provider; the error
/// names the providers it does offer.
pub fn check_accelerator(store: &ModelStore, accelerator: &Accelerator) -> Result<(), ModelError> {
    let report = execution_providers(store)?;
    let provider = accelerator.kind.provider();
    if report.providers.iter().any(|p| p == provider) {
        return Ok(());
    }
    Err(ModelError::ProviderUnavailable {
        accelerator: *accelerator,
        library: runtime_library(store),
        available: report.providers.join(", "),
    })
}

impl OnnxModel {
    /// Load `file` (relative to the cache, checked against the manifest) with `threads`
    /// intra-op threads (0 = ONNX Runtime's default), on the CPU.
    pub fn load(store: &ModelStore, file: &str, threads: usize) -> Result<Self, ModelError> {
        Self::load_with(store, file, &SessionOptions::cpu(threads))
    }

    /// Load `file` as `options` say: on an accelerator, its execution provider is checked
    /// ([`check_accelerator`]) and registered so that failing to register it is an error,
    /// not a session silently on the CPU. Nodes the provider cannot run still run on the CPU
    /// provider, as ONNX Runtime places them.
    pub fn load_with(
        store: &ModelStore,
        file: &str,
        options: &SessionOptions,
    ) -> Result<Self, ModelError> {
        let env = environment(store)?;
        if let Some(a) = &options.accelerator {
            check_accelerator(store, a)?;
        }
        let path = store.verified(file)?;
        Self::load_path(env, &path, options)
    }

    fn load_path(
        env: &Environment,
        path: &Path,
        options: &SessionOptions,
    ) -> Result<Self, ModelError> {
        let threads = options.threads;
        let load = |e: ort::Error| ModelError::Load {
            path: path.to_path_buf(),
            reason: e.to_string(),
        };
        let mut builder = Session::builder(env)
            .map_err(load)?
            .with_optimization_level(GraphOptimizationLevel::Level3)
            .map_err(|e| load(e.into()))?;
        if let Some(a) = &options.accelerator {
            let device = i32::try_from(a.device).unwrap_or(i32::MAX);
            let ep = match a.kind {
                AcceleratorKind::Cuda => ep::CUDA::default().with_device_id(device).build(),
                AcceleratorKind::TensorRt => ep::TensorRT::default().with_device_id(device).build(),
                AcceleratorKind::Rocm => ep::ROCm::default().with_device_id(device).build(),
            };
            builder = builder
                .with_execution_providers([ep.error_on_failure()])
                .map_err(|e| load(e.into()))?;
        }
        if threads > 0 {
            builder = builder
                .with_intra_threads(threads)
                .map_err(|e| load(e.into()))?
                .with_inter_threads(1)
                .map_err(|e| load(e.into()))?;
        }
        // spinning worker threads would steal the CPU the other roles need
        builder = builder
            .with_intra_op_spinning(false)
            .map_err(|e| load(e.into()))?;
        let session = builder.commit_from_file(path).map_err(load)?;
        let name = path
            .file_stem()
            .map_or_else(|| "model".into(), |s| s.to_string_lossy().into_owned());
        Ok(Self {
            session,
            name,
            path: path.to_path_buf(),
        })
    }

    /// The model's name (file stem).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The session, to run it.
    pub fn session(&mut self) -> &mut Session {
        &mut self.session
    }

    /// A custom metadata entry of the model (e.g. class names).
    pub fn metadata(&self, key: &str) -> Option<String> {
        self.session.metadata().ok()?.custom(key)
    }

    /// Run the model on one f32 `input` of `shape` and hand its first output, read as an
    /// f32 tensor (shape, values), to `read`; `read`'s error becomes [`ModelError::Interface`].
    pub fn run_f32<R>(
        &mut self,
        shape: &[usize],
        input: &[f32],
        read: impl FnOnce(&[i64], &[f32]) -> Result<R, String>,
    ) -> Result<R, ModelError> {
        let tensor =
            TensorRef::from_array_view((shape, input)).map_err(|e| self.inference_error(e))?;
        let name = &self.name;
        let outputs =
            self.session
                .run(ort::inputs![tensor])
                .map_err(|e| ModelError::Inference {
                    model: name.clone(),
                    reason: e.to_string(),
                })?;
        let interface = |reason: String| ModelError::Interface {
            model: name.clone(),
            reason,
        };
        let (out_shape, values) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| interface(e.to_string()))?;
        read(out_shape, values).map_err(interface)
    }

    /// An [`ModelError::Inference`] for this model.
    pub fn inference_error(&self, reason: impl std::fmt::Display) -> ModelError {
        ModelError::Inference {
            model: self.name.clone(),
            reason: reason.to_string(),
        }
    }

    /// An [`ModelError::Interface`] for this model.
    pub fn interface_error(&self, reason: impl std::fmt::Display) -> ModelError {
        ModelError::Interface {
            model: self.name.clone(),
            reason: reason.to_string(),
        }
    }
}
