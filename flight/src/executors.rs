//! What a flight would run on: the executor registry resolved from a workflow, and the
//! accelerators the provisioned ONNX Runtime offers (`aeris validate` shows both; a flight
//! records the accelerators in its supervisor's registry).

use aeris_orchestrator::executors::{AcceleratorInfo, ExecutorRegistry, accelerators_from};
use aeris_orchestrator::launch::{PlanError, plan_launch};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::accelerator::AcceleratorKind;
use aeris_runtime::affinity::CpuSet;
use aeris_schemas::RoleKind;
use aeris_schemas::accelerator::Accelerator;

/// Whether this build's language-model engine can offload a model's layers to an
/// accelerator. The binary passes llama.cpp's (`aeris_llm::offload_check`), so that this
/// library does not link llama.cpp; a flight started without one leaves the check to each
/// language-model role, when it loads.
pub type OffloadCheck = fn(Accelerator) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;

/// What the provisioned ONNX Runtime reports: its execution providers and the accelerator
/// devices they found; `None` when no runtime is provisioned (a flight needs none unless
/// it runs model roles).
pub fn onnx_accelerators() -> Option<(Vec<String>, Vec<AcceleratorInfo>)> {
    let store = aeris_models::ModelStore::open(None).ok()?;
    let report = aeris_models::execution_providers(&store).ok()?;
    let devices: Vec<(String, String, String, u32)> = report
        .devices
        .iter()
        .map(|d| {
            (
                d.provider.clone(),
                d.kind.as_str().to_string(),
                d.vendor.clone(),
                d.device_id,
            )
        })
        .collect();
    Some((report.providers, accelerators_from(&devices)))
}

/// The executor registry a flight of `workflow` would start with (declared executors
/// resolved against the CPUs this process may use, the rest discovered), with the
/// accelerators ONNX Runtime offers.
pub fn planned_registry(workflow: &Workflow) -> Result<ExecutorRegistry, PlanError> {
    let online = CpuSet::of_task(0).unwrap_or_else(|_| CpuSet::available());
    // placeholder ports, distinct per vehicle (nothing is opened): a flight of several
    // vehicles needs one link each
    let mut placeholder = 0u16;
    let plan = plan_launch(workflow, "validate", None, &online, || {
        placeholder += 1;
        Ok(placeholder)
    })?;
    let mut registry = ExecutorRegistry::discover(&plan.executors, &online);
    if let Some((providers, accelerators)) = onnx_accelerators() {
        registry.set_accelerators(providers, accelerators);
    }
    Ok(registry)
}

/// One line on the registry's accelerators, for logs.
pub fn accelerator_line(registry: &ExecutorRegistry) -> String {
    let Some(providers) = registry.providers() else {
        return "accelerators: unknown (no ONNX Runtime could be loaded to ask)".into();
    };
    let providers = providers
        .iter()
        .map(|p| p.strip_suffix("ExecutionProvider").unwrap_or(p))
        .collect::<Vec<_>>()
        .join(", ");
    if registry.accelerators().is_empty() {
        // ONNX Runtime lists devices only for the providers it registers itself: a CUDA,
        // TensorRT or ROCm provider works without its device being listed (seen on an H100)
        let gpu = registry.providers().is_some_and(|ps| {
            AcceleratorKind::ALL
                .iter()
                .any(|k| ps.iter().any(|p| p == k.provider()))
        });
        return if gpu {
            format!(
                "accelerators: no device listed by ONNX Runtime; its providers: {providers} (an executor's `accelerator` names the device)"
            )
        } else {
            format!("accelerators: none (ONNX Runtime providers: {providers})")
        };
    }
    let list = registry
        .accelerators()
        .iter()
        .map(|a| format!("{} ({} {} via {})", a.name, a.vendor, a.kind, a.provider))
        .collect::<Vec<_>>()
        .join(", ");
    format!("accelerators: {list} (ONNX Runtime providers: {providers})")
}

/// An accelerator executor whose accelerator this host cannot use for the roles on it.
#[derive(Debug, thiserror::Error)]
#[error("[executors.{executor}]")]
pub struct AcceleratorError {
    /// The executor.
    pub executor: String,
    /// Why.
    #[source]
    pub source: AcceleratorRefusal,
}

/// Why an accelerator executor's roles cannot use it.
#[derive(Debug, thiserror::Error)]
pub enum AcceleratorRefusal {
    /// For its ONNX model roles: the model cache or runtime is missing, or the provider is not
    /// offered (the error names those that are).
    #[error(transparent)]
    Onnx(#[from] aeris_models::ModelError),
    /// For its language-model roles: this build's language-model engine cannot offload to
    /// it ([`OffloadCheck`]).
    #[error(transparent)]
    Language(Box<dyn std::error::Error + Send + Sync>),
}

/// Check every accelerator executor on the flight's host that a role starts on (or falls
/// back to when its link to another host is lost): for its ONNX model roles, against the
/// ONNX Runtime they would load (the provisioned one, or `$AERIS_ONNXRUNTIME`); for its
/// language-model roles, with `offload` (this build's llama.cpp, where GPU offload is the
/// cargo feature `cuda`; without one, each role checks when it loads). A provider or build
/// that cannot run them is refused before any role starts. An
/// executor no role starts on is checked when a role is moved there (`aeris migrate`);
/// another host's are checked there, when their roles load; whether a GPU device is present
/// is checked by each language-model role when it loads.
pub fn check_accelerators(
    workflow: &Workflow,
    offload: Option<OffloadCheck>,
) -> Result<(), AcceleratorError> {
    let starts_on = |r: &aeris_orchestrator::workflow::RoleDecl, name: &str| {
        r.executor.as_deref() == Some(name)
            || r.fallback.as_ref().and_then(|f| f.executor.as_deref()) == Some(name)
    };
    // the model cache (and its manifest) is read once, for the first accelerator checked
    let mut store = None;
    for ex in workflow.executors.iter().filter(|e| e.host.is_none()) {
        let Some(accelerator) = ex.accelerator else {
            continue;
        };
        let err = |source: AcceleratorRefusal| AcceleratorError {
            executor: ex.name.clone(),
            source,
        };
        let language = |kind: RoleKind, variant: &str| {
            aeris_orchestrator::workflow::LANGUAGE_MODEL_VARIANTS.contains(&(kind, variant))
        };
        let (mut onnx, mut llm) = (false, false);
        for r in workflow.roles.iter().filter(|r| starts_on(r, &ex.name)) {
            if language(r.kind, &r.variant) {
                llm = true;
            } else {
                onnx = true;
            }
        }
        if llm && let Some(check) = offload {
            check(accelerator).map_err(|e| err(AcceleratorRefusal::Language(e)))?;
        }
        if onnx {
            let store = match &mut store {
                Some(s) => s,
                None => {
                    store.insert(aeris_models::ModelStore::open(None).map_err(|e| err(e.into()))?)
                }
            };
            aeris_models::check_accelerator(store, &accelerator).map_err(|e| err(e.into()))?;
        }
    }
    Ok(())
}
