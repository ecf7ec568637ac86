//! The execution providers of the provisioned ONNX Runtime, as the executor registry asks
//! for them: the CPU provider is always compiled in and offers this machine's CPU.

use aeris_models::{DeviceKind, ModelStore, execution_providers};

#[test]
fn the_runtime_reports_its_providers_and_the_cpu_device() {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let report = execution_providers(&store).unwrap();
    assert!(
        report.providers.iter().any(|p| p == "CPUExecutionProvider"),
        "{report:?}"
    );
    // asking twice gives the same answer (the runtime is loaded once per process)
    assert_eq!(execution_providers(&store).unwrap(), report);
    let cpu = report
        .devices
        .iter()
        .find(|d| d.provider == "CPUExecutionProvider")
        .unwrap_or_else(|| panic!("no CPU device: {report:?}"));
    assert_eq!(cpu.kind, DeviceKind::Cpu);
    assert!(!cpu.vendor.is_empty());
    println!("{report:?}");
}
