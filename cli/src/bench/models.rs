//! `aeris bench models`: every model measured in a child process of its own
//! (`aeris bench model-probe`), one table row as each finishes.

use aeris_bench::models::{self, MODEL_CASES, ModelRow, ModelsReport};
use aeris_orchestrator::priority::{FlightPriority, PriorityMode};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::accelerator::Accelerator;
use anyhow::{Context, Result, bail};
use clap::Args;
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Command, Stdio};

/// Arguments of `aeris bench models`.
#[derive(Debug, Args)]
pub struct ModelsArgs {
    /// Only these models (default: all): ppocr, yolov3-tiny, yolov8-320n, minilm, smollm2,
    /// gemma3.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Timed runs per model (after one warm-up run).
    #[arg(long, default_value_t = 10)]
    pub runs: usize,
    /// Threads per model (the roles' default: 1 for ONNX models, 2 for language models).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Model cache (default: $AERIS_MODELS or ~/.cache/aeris/models).
    #[arg(long, value_name = "DIR")]
    pub models_dir: Option<PathBuf>,
    /// Run the models on this accelerator (`cuda:0`, `tensorrt:0`, `rocm:0`): ONNX models
    /// with its ONNX Runtime execution provider, language models with every layer offloaded
    /// (CUDA, in a build with the `cuda` feature). A model that cannot is reported as failed.
    #[arg(long, value_name = "KIND:DEVICE")]
    pub accelerator: Option<Accelerator>,
    /// Busy processes started outside the models for the run (unpinned, normal priority): the
    /// models on a shared machine.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub outside_load: usize,
    /// How the models get priority over outside work, as a flight's roles do: `auto` (the
    /// flight's CPU control group where permitted, else nice -5), `nice` or `off`.
    #[arg(long, value_name = "MODE", default_value = "auto", value_parser = crate::bench::flight::parse_priority)]
    pub priority: PriorityMode,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of the hidden `aeris bench model-probe` (one model, one JSON line).
#[derive(Debug, Args)]
pub struct ModelProbeArgs {
    /// Model name.
    #[arg(long)]
    pub model: String,
    /// Timed runs.
    #[arg(long)]
    pub runs: usize,
    /// Threads.
    #[arg(long)]
    pub threads: usize,
    /// Model cache.
    #[arg(long)]
    pub models_dir: Option<PathBuf>,
    /// Accelerator.
    #[arg(long)]
    pub accelerator: Option<Accelerator>,
}

fn default_threads(model: &str) -> usize {
    if matches!(model, "smollm2" | "gemma3") {
        2
    } else {
        1
    }
}

/// `aeris bench models`.
pub fn run(a: ModelsArgs) -> Result<()> {
    for name in &a.only {
        if models::model_case(name).is_none() {
            let known: Vec<&str> = MODEL_CASES.iter().map(|c| c.name).collect();
            bail!("unknown model `{name}`; known: {}", known.join(", "));
        }
    }
    let exe = std::env::current_exe().context("cannot find this executable")?;
    let on = a
        .accelerator
        .map_or_else(|| "the CPU".to_string(), |x| x.to_string());
    println!(
        "models on {on}: load time, latency over {} runs after a warm-up, resident memory; one process per model; {} busy processes outside",
        a.runs, a.outside_load
    );
    let _load = aeris_bench::flights::BusyProcesses::start(None, a.outside_load)?;
    // each model runs with the priority a flight gives its role: the figure beside outside
    // load is the one a flight sees
    let priority =
        FlightPriority::establish(&format!("bench-models-{}", std::process::id()), a.priority);
    println!(
        "models' priority over outside work: {}",
        priority.priority()
    );
    println!(
        "{:<12} {:<18} {:>7} {:>9} {:>9} {:>8} {:>9} {:>7}  output",
        "model", "role", "load_s", "p50_ms", "p95_ms", "rss_MiB", "model_MiB", "tok/s"
    );
    let mut rows: Vec<ModelRow> = Vec::new();
    let mut failures: Vec<String> = Vec::new();
    let mut threads_used = 0;
    for case in MODEL_CASES
        .iter()
        .filter(|c| a.only.is_empty() || a.only.iter().any(|o| o == c.name))
    {
        let threads = a.threads.unwrap_or_else(|| default_threads(case.name));
        threads_used = threads_used.max(threads);
        let mut cmd = Command::new(&exe);
        cmd.args(["bench", "model-probe", "--model", case.name])
            .args(["--runs", &a.runs.to_string()])
            .args(["--threads", &threads.to_string()])
            .stdin(Stdio::null())
            .stderr(Stdio::piped())
            .stdout(Stdio::piped());
        if let Some(dir) = &a.models_dir {
            cmd.arg("--models-dir").arg(dir);
        }
        if let Some(x) = a.accelerator {
            cmd.args(["--accelerator", &x.to_string()]);
        }
        let child = priority.for_child();
        // SAFETY: apply_in_child makes only async-signal-safe calls (a write, setpriority).
        unsafe {
            cmd.pre_exec(move || {
                child.apply_in_child();
                Ok(())
            })
        };
        let out = cmd
            .output()
            .with_context(|| format!("cannot start the probe of `{}`", case.name))?;
        let stdout = String::from_utf8_lossy(&out.stdout);
        let row = stdout
            .lines()
            .last()
            .and_then(|l| serde_json::from_str::<ModelRow>(l).ok());
        match (out.status.success(), row) {
            (true, Some(r)) => {
                println!(
                    "{:<12} {:<18} {:>7.2} {:>9.1} {:>9.1} {:>8.0} {:>9.0} {:>7}  {}",
                    r.model,
                    r.role,
                    r.load_s,
                    r.p50_ms,
                    r.p95_ms,
                    r.rss_mib,
                    r.rss_model_mib,
                    r.tokens_per_s.map_or("-".into(), |t| format!("{t:.1}")),
                    shorten(&r.output, 60)
                );
                rows.push(r);
            }
            _ => {
                let stderr = String::from_utf8_lossy(&out.stderr);
                // the probe's own error line, without its `aeris: error: ` prefix
                let why = stderr
                    .lines()
                    .rev()
                    .find(|l| !l.trim().is_empty())
                    .map(|l| l.strip_prefix("aeris: error: ").unwrap_or(l))
                    .unwrap_or("no output")
                    .to_string();
                println!("{:<12} failed: {why}", case.name);
                failures.push(format!("{}: {why}", case.name));
            }
        }
    }
    if a.json {
        let report = ModelsReport {
            threads: threads_used,
            accelerator: a.accelerator.map(|x| x.to_string()),
            outside_load: a.outside_load,
            priority: priority.priority().mechanism().to_string(),
            priority_detail: priority.priority().to_string(),
            rows,
        };
        crate::bench::json::print(&report)?;
    }
    if !failures.is_empty() {
        bail!(
            "{} model(s) failed:\n  {}",
            failures.len(),
            failures.join("\n  ")
        );
    }
    Ok(())
}

fn shorten(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        let mut t: String = s.chars().take(n - 1).collect();
        t.push('…');
        t
    }
}

/// `aeris bench model-probe`: measure one model here and print its row as JSON.
pub fn probe(a: ModelProbeArgs) -> Result<()> {
    let case =
        models::model_case(&a.model).with_context(|| format!("unknown model `{}`", a.model))?;
    let store = aeris_models::ModelStore::open(a.models_dir.as_deref())?;
    let workflow = Workflow::builtin_default().context("built-in default workflow")?;
    // the parent (`aeris bench models`) names the model on the line it prints
    let on = aeris_models::SessionOptions {
        threads: a.threads,
        accelerator: a.accelerator,
    };
    let row = models::probe(case, &store, &on, a.runs, &workflow.mission)?;
    println!("{}", serde_json::to_string(&row)?);
    Ok(())
}
