//! The machine a figure came from, carried in every `aeris bench` JSON (`"machine"`), so two
//! runs on different machines are told apart before they are compared: the CPU's model and
//! the instruction-set flags the models' kernels use, the cores, the build profile, the time
//! the hypervisor stole from the machine's CPUs during the run (`/proc/stat`), and a short
//! calibration figure measured at the start (a fixed matrix product, GFLOP/s on one thread).

use serde::Serialize;
use std::time::Instant;

/// Instruction-set flags that decide the speed of the models' kernels (ggml, ONNX Runtime):
/// those of the CPU that are listed here are reported.
const KERNEL_FLAGS: &[&str] = &[
    "avx2",
    "fma",
    "f16c",
    "avx512f",
    "avx512_vnni",
    "avx512_bf16",
    "avx_vnni",
    "amx_tile",
    "amx_bf16",
    "amx_int8",
    // aarch64 (`Features` in /proc/cpuinfo)
    "asimd",
    "asimddp",
    "sve",
    "i8mm",
    "bf16",
];

/// A run's start: what was read then.
#[derive(Debug, Clone)]
pub struct MachineRun {
    cpu_model: String,
    flags: Vec<String>,
    cores: usize,
    calibration_gflops: f64,
    started: Instant,
    steal_ticks: Option<u64>,
    all_ticks: Option<u64>,
}

/// What a report says of its machine.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// The CPU's model name (`/proc/cpuinfo`; `unknown` where it names none).
    pub cpu_model: String,
    /// The [`KERNEL_FLAGS`] this CPU has.
    pub flags: Vec<String>,
    /// CPUs this process may use.
    pub cores: usize,
    /// `release` or `debug`: the profile of the `aeris` binary that measured.
    pub build_profile: &'static str,
    /// A fixed single-threaded f32 matrix product (128 x 128, best of 5), GFLOP/s: a figure to
    /// compare two machines by.
    pub calibration_gflops: f64,
    /// Seconds from the run's start to its report.
    pub run_s: f64,
    /// CPU time the hypervisor stole over the run, as a share of all CPU time (`/proc/stat`;
    /// `None` where it cannot be read).
    pub steal_share: Option<f64>,
}

impl MachineRun {
    /// Read the machine now (takes a few milliseconds: the calibration).
    pub fn start() -> Self {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let (steal_ticks, all_ticks) = cpu_ticks().unzip();
        MachineRun {
            cpu_model: cpu_model(&cpuinfo),
            flags: kernel_flags(&cpuinfo),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            calibration_gflops: calibrate(),
            started: Instant::now(),
            steal_ticks,
            all_ticks,
        }
    }

    /// What to report, at the run's end.
    pub fn report(&self) -> Machine {
        let steal_share = match (cpu_ticks(), self.steal_ticks, self.all_ticks) {
            (Some((steal, all)), Some(steal0), Some(all0)) if all > all0 => {
                Some(steal.saturating_sub(steal0) as f64 / (all - all0) as f64)
            }
            _ => None,
        };
        Machine {
            cpu_model: self.cpu_model.clone(),
            flags: self.flags.clone(),
            cores: self.cores,
            build_profile: if cfg!(debug_assertions) {
                "debug"
            } else {
                "release"
            },
            calibration_gflops: self.calibration_gflops,
            run_s: self.started.elapsed().as_secs_f64(),
            steal_share,
        }
    }
}

/// `report` as a JSON object with `"machine"` added (a report that is not an object is
/// wrapped: `{"report": ..., "machine": ...}`).
pub fn stamped<T: Serialize>(
    report: &T,
    machine: &MachineRun,
) -> Result<serde_json::Value, serde_json::Error> {
    let machine = serde_json::to_value(machine.report())?;
    Ok(match serde_json::to_value(report)? {
        serde_json::Value::Object(mut fields) => {
            fields.insert("machine".into(), machine);
            serde_json::Value::Object(fields)
        }
        other => serde_json::json!({ "report": other, "machine": machine }),
    })
}

fn cpu_model(cpuinfo: &str) -> String {
    ["model name", "Model", "Hardware"]
        .iter()
        .find_map(|key| {
            cpuinfo.lines().find_map(|l| {
                let (k, v) = l.split_once(':')?;
                (k.trim() == *key && !v.trim().is_empty()).then(|| v.trim().to_string())
            })
        })
        .unwrap_or_else(|| "unknown".into())
}

fn kernel_flags(cpuinfo: &str) -> Vec<String> {
    let have: Vec<&str> = cpuinfo
        .lines()
        .find_map(|l| {
            let (k, v) = l.split_once(':')?;
            matches!(k.trim(), "flags" | "Features").then_some(v)
        })
        .map(|v| v.split_whitespace().collect())
        .unwrap_or_default();
    KERNEL_FLAGS
        .iter()
        .filter(|f| have.contains(f))
        .map(|f| f.to_string())
        .collect()
}

/// `(steal, all)` ticks of the machine's CPUs from `/proc/stat`'s `cpu` line.
fn cpu_ticks() -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    parse_cpu_ticks(&stat)
}

fn parse_cpu_ticks(stat: &str) -> Option<(u64, u64)> {
    let line = stat.lines().find(|l| l.starts_with("cpu "))?;
    let ticks: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .filter_map(|t| t.parse().ok())
        .collect();
    // user nice system idle iowait irq softirq steal [guest guest_nice: inside user/nice]
    let steal = *ticks.get(7)?;
    Some((steal, ticks.iter().take(8).sum()))
}

/// Best of five single-threaded 128 x 128 f32 matrix products, GFLOP/s.
fn calibrate() -> f64 {
    const N: usize = 128;
    let a: Vec<f32> = (0..N * N).map(|i| (i % 7) as f32 * 0.5).collect();
    let b: Vec<f32> = (0..N * N).map(|i| (i % 5) as f32 * 0.25).collect();
    let mut c = vec![0f32; N * N];
    let mut best = f64::MAX;
    for _ in 0..5 {
        let t = Instant::now();
        for i in 0..N {
            for k in 0..N {
                let aik = a[i * N + k];
                for j in 0..N {
                    c[i * N + j] += aik * b[k * N + j];
                }
            }
        }
        best = best.min(t.elapsed().as_secs_f64());
        std::hint::black_box(&mut c);
    }
    (2 * N * N * N) as f64 / best.max(1e-9) / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_is_named_and_its_kernel_flags_listed() {
        let x86 = "processor\t: 0\nmodel name\t: Intel(R) Xeon(R) Processor\nflags\t\t: fpu avx2 fma avx512f amx_tile sse\n";
        assert_eq!(cpu_model(x86), "Intel(R) Xeon(R) Processor");
        assert_eq!(kernel_flags(x86), ["avx2", "fma", "avx512f", "amx_tile"]);
        let arm =
            "processor\t: 0\nFeatures\t: fp asimd asimddp\nModel\t: NVIDIA Jetson Orin Nano\n";
        assert_eq!(cpu_model(arm), "NVIDIA Jetson Orin Nano");
        assert_eq!(kernel_flags(arm), ["asimd", "asimddp"]);
        assert_eq!(cpu_model(""), "unknown");
    }

    #[test]
    fn steal_is_the_eighth_field_and_all_ticks_exclude_the_guest_ones() {
        let stat = "cpu  100 1 10 800 2 0 3 4 50 0\ncpu0 50 0 5 400 1 0 1 2 0 0\n";
        assert_eq!(parse_cpu_ticks(stat), Some((4, 920)));
        assert_eq!(parse_cpu_ticks("cpu0 1 2 3\n"), None);
    }

    #[test]
    fn a_report_is_stamped_with_its_machine() {
        #[derive(Serialize)]
        struct Report {
            ct_mean_s: f64,
        }
        let run = MachineRun::start();
        let v = stamped(&Report { ct_mean_s: 0.5 }, &run).unwrap();
        assert_eq!(v["ct_mean_s"], 0.5);
        assert!(v["machine"]["cores"].as_u64().unwrap() >= 1);
        assert!(v["machine"]["calibration_gflops"].as_f64().unwrap() > 0.0);
        let rows = stamped(&vec![1, 2], &run).unwrap();
        assert_eq!(rows["report"], serde_json::json!([1, 2]));
        assert!(rows["machine"].is_object());
    }
}
