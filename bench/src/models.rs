//! `bench models`: every model a role hosts, each measured in a process of its own (as a
//! role hosts it): load time, latency p50/p95 over repeated runs on real inputs, resident
//! memory, and for language models tokens/s and the tokens of a decision.
//!
//! Inputs: the text reader reads the village's LAKE VIEW sign rendered by the built-in
//! renderer at the camera's resolution; the detectors see Ultralytics' `bus.jpg` from the
//! model cache; the embedder embeds instruction cues; the language models decide on
//! observations along the village mission (position, a composed S_t, their own previous
//! decision, the planner's plan), so each prompt differs from the last as it does in flight.

use crate::error::BenchError;
use aeris_llm::{DecisionView, LanguageReasoner, Observation, ReasonerConfig};
use aeris_models::{ModelStore, OcrReader, SessionOptions, TextEmbedder};
use aeris_roles::planner::Planner;
use aeris_runtime::MissionSpec;
use aeris_schemas::{FixedText, PerceptionState};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One model the benchmark knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelCase {
    /// Name on the command line and in reports.
    pub name: &'static str,
    /// The role (kind / variant) that hosts it.
    pub role: &'static str,
    /// Runtime that runs it.
    pub runtime: &'static str,
    /// What one run does.
    pub input: &'static str,
}

/// Every model, in report order.
pub const MODEL_CASES: &[ModelCase] = &[
    ModelCase {
        name: "ppocr",
        role: "text-reader/ppocr",
        runtime: "onnxruntime",
        input: "rendered LAKE VIEW sign, 320x240 (det + rec)",
    },
    ModelCase {
        name: "yolov3-tiny",
        role: "detector/yolo",
        runtime: "onnxruntime",
        input: "bus.jpg 810x1080",
    },
    ModelCase {
        name: "yolov8-320n",
        role: "detector/yolov8",
        runtime: "onnxruntime",
        input: "bus.jpg 810x1080",
    },
    ModelCase {
        name: "minilm",
        role: "cues/minilm",
        runtime: "onnxruntime",
        input: "4 subgoal texts + 4 cues, one batch",
    },
    ModelCase {
        name: "smollm2",
        role: "reasoning/smollm2",
        runtime: "llama.cpp",
        input: "one decision, village mission",
    },
    ModelCase {
        name: "gemma3",
        role: "reasoning/gemma3",
        runtime: "llama.cpp",
        input: "one decision, village mission",
    },
];

/// The case named `name`.
pub fn model_case(name: &str) -> Option<&'static ModelCase> {
    MODEL_CASES.iter().find(|c| c.name == name)
}

/// One row of the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelRow {
    /// Model name ([`MODEL_CASES`]).
    pub model: String,
    /// Role that hosts it.
    pub role: String,
    /// Runtime.
    pub runtime: String,
    /// What one run does.
    pub input: String,
    /// Seconds from nothing loaded to ready (hash check, weights, session / context).
    pub load_s: f64,
    /// Timed runs (after one warm-up run).
    pub runs: usize,
    /// Median latency of one run (ms).
    pub p50_ms: f64,
    /// 95th percentile latency (ms).
    pub p95_ms: f64,
    /// Resident memory of the process after the runs (MiB).
    pub rss_mib: f64,
    /// Resident memory the model added over the bare process (MiB).
    pub rss_model_mib: f64,
    /// Language models: generated tokens per second (mean over the runs).
    pub tokens_per_s: Option<f64>,
    /// Language models: mean prompt tokens evaluated per decision (not reused).
    pub prompt_tokens_new: Option<f64>,
    /// Language models: mean tokens generated per decision.
    pub generated_tokens: Option<f64>,
    /// What the last run produced, for a glance that it works (a decision, a label...).
    pub output: String,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelsReport {
    /// Threads each model was given.
    pub threads: usize,
    /// The accelerator the models ran on (`cuda:0`; absent: the CPU).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accelerator: Option<String>,
    /// Busy processes that ran outside the models meanwhile.
    #[serde(default)]
    pub outside_load: usize,
    /// How the models got priority over them (`cgroup-v2`, `cgroup-v1`, `nice`, `none`).
    #[serde(default)]
    pub priority: String,
    /// The same in words.
    #[serde(default)]
    pub priority_detail: String,
    /// One row per model.
    pub rows: Vec<ModelRow>,
}

/// Resident set size of this process (MiB) from /proc/self/status.
pub fn rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

/// A model loaded and ready to run once more.
trait Probe {
    /// One run; returns a short description of its output.
    fn run(&mut self, i: usize) -> Result<String, BenchError>;
    /// Language-model figures of the last run: (tokens/s, new prompt tokens, generated).
    fn llm_figures(&self) -> Option<(f64, usize, usize)> {
        None
    }
}

struct OcrProbe {
    reader: OcrReader,
    rgb: Vec<u8>,
    width: usize,
    height: usize,
    out: Vec<aeris_models::TextRegion>,
}

impl Probe for OcrProbe {
    fn run(&mut self, _: usize) -> Result<String, BenchError> {
        self.reader
            .read(&self.rgb, self.width, self.height, &mut self.out)?;
        Ok(self
            .out
            .iter()
            .map(|t| t.text.as_str())
            .collect::<Vec<_>>()
            .join(" "))
    }
}

struct DetectorProbe {
    detector: aeris_models::Detector,
    rgb: Vec<u8>,
    width: usize,
    height: usize,
    out: Vec<aeris_models::DetectedBox>,
}

impl Probe for DetectorProbe {
    fn run(&mut self, _: usize) -> Result<String, BenchError> {
        self.detector
            .detect(&self.rgb, self.width, self.height, &mut self.out)?;
        let names = self.detector.names();
        Ok(self
            .out
            .iter()
            .take(6)
            .map(|b| {
                format!(
                    "{} {:.2}",
                    names.get(b.class_id).map_or("?", |s| s.as_str()),
                    b.score
                )
            })
            .collect::<Vec<_>>()
            .join(", "))
    }
}

struct EmbedProbe {
    embedder: TextEmbedder,
    texts: Vec<String>,
    out: Vec<aeris_models::embed::Embedding>,
}

impl Probe for EmbedProbe {
    fn run(&mut self, _: usize) -> Result<String, BenchError> {
        let texts: Vec<&str> = self.texts.iter().map(String::as_str).collect();
        self.embedder.embed_into(&texts, &mut self.out)?;
        let best = (4..self.out.len())
            .map(|c| aeris_models::cosine(&self.out[3], &self.out[c]))
            .fold(f32::NEG_INFINITY, f32::max);
        Ok(format!(
            "{} embeddings; best cue for step 4: {best:.2}",
            self.out.len()
        ))
    }
}

struct LlmProbe {
    reasoner: LanguageReasoner,
    planner: Planner,
    fresh: Planner,
    states: Vec<PerceptionState>,
    previous: Option<DecisionView>,
    last: Option<(f64, usize, usize)>,
}

/// Observations along the village mission: on the helipad, climbing, flying north, at the
/// red roof, flying east, near the sign.
const PATH: [([f32; 3], bool); 6] = [
    ([0.0, 0.0, 0.0], true),
    ([0.0, 0.0, 11.6], false),
    ([30.0, 0.0, 12.0], false),
    ([61.0, 1.0, 12.0], false),
    ([62.0, 40.0, 12.0], false),
    ([44.0, 86.0, 3.0], false),
];

/// A composed S_t as the image-to-text role writes it.
fn sample_state(i: usize) -> PerceptionState {
    let summaries = [
        "road ahead 40 m; house right 25 m",
        "red roof ahead 34 m; road ahead",
        "red roof ahead 6 m; road right",
        "blue water tower ahead 20 m; road ahead",
        "reads \"LAKE VIEW\"; yellow sign ahead 9 m",
        "lake left 30 m; trees right",
    ];
    let mut s = PerceptionState {
        summary: FixedText::from_str_truncated(summaries[i % summaries.len()]),
        ..PerceptionState::default()
    };
    s.detection_count = 2;
    s.detections[0].label = FixedText::from_str_truncated("house");
    s.detections[0].score = 0.7;
    s.detections[0].range_m = 25.0 + i as f32;
    s.detections[1].label = FixedText::from_str_truncated("car");
    s.detections[1].score = 0.5;
    s.detections[1].range_m = 40.0 - i as f32;
    s.cue_count = 1;
    s.cues[0].text = FixedText::from_str_truncated("red-roofed building");
    s.cues[0].score = 0.6;
    s
}

impl Probe for LlmProbe {
    fn run(&mut self, i: usize) -> Result<String, BenchError> {
        let (position, landed) = PATH[i % PATH.len()];
        if i.is_multiple_of(PATH.len()) {
            // the path starts over on the helipad: so does the mission
            self.planner = self.fresh.clone();
            self.previous = None;
        }
        let plan = DecisionView::from_decision(&self.planner.decide(position, 0.0, landed, None));
        let obs = Observation {
            position,
            yaw: 0.0,
            landed,
            state: Some(&self.states[i % self.states.len()]),
            previous: self.previous.as_ref(),
            plan: Some(&plan),
            sighted: &[],
        };
        let t = self.reasoner.decide(&obs)?;
        self.last = Some((
            t.tokens_per_s(),
            t.prompt_tokens - t.reused_tokens,
            t.generated_tokens,
        ));
        self.previous = Some(t.view);
        Ok(t.text)
    }

    fn llm_figures(&self) -> Option<(f64, usize, usize)> {
        self.last
    }
}

/// Decode `file` of the cache to packed RGB8.
fn load_rgb(store: &ModelStore, file: &str) -> Result<(Vec<u8>, usize, usize), BenchError> {
    let path = store.verified(file)?;
    let img = image::open(&path)
        .map_err(|e| BenchError::Config(format!("cannot decode {}: {e}", path.display())))?
        .to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    Ok((img.into_raw(), w, h))
}

/// The frame the OCR probe reads: the LAKE VIEW sign of the built-in village, rendered.
#[cfg(feature = "sim")]
fn sign_frame() -> Result<(Vec<u8>, usize, usize), BenchError> {
    // the flight camera's geometry (CameraSpec's default: 320 x 240, 90 degrees)
    let (w, h) = (320u32, 240u32);
    let renderer = aeris_sim::render::Renderer::new(w, h, 90f32.to_radians())
        .map_err(|e| BenchError::Config(format!("renderer: {e}")))?;
    let world = aeris_sim::world::World::builtin("village")
        .ok_or_else(|| BenchError::Config("no built-in world `village`".into()))?;
    let mut rgb = vec![0u8; renderer.rgb_len()];
    let mut depth = vec![0u8; renderer.depth_len()];
    // 6 m north of the LAKE VIEW sign, facing south at its height
    renderer
        .render(
            &world,
            [40.0, 88.0, 4.0],
            std::f32::consts::PI,
            &mut rgb,
            &mut depth,
        )
        .map_err(|e| BenchError::Config(format!("render: {e}")))?;
    Ok((rgb, w as usize, h as usize))
}

/// Without the simulator there is no sign to render for the OCR probe.
#[cfg(not(feature = "sim"))]
fn sign_frame() -> Result<(Vec<u8>, usize, usize), BenchError> {
    Err(BenchError::Config(
        "the OCR probe reads a sign rendered by the built-in simulator, and this build has none \
         (build with the `sim` feature)"
            .into(),
    ))
}

fn load_probe(
    case: &ModelCase,
    store: &ModelStore,
    on: &SessionOptions,
    mission: &MissionSpec,
) -> Result<Box<dyn Probe>, BenchError> {
    let threads = on.threads;
    Ok(match case.name {
        "ppocr" => {
            let (rgb, width, height) = sign_frame()?;
            Box::new(OcrProbe {
                reader: OcrReader::load(store, on)?,
                rgb,
                width,
                height,
                out: Vec::new(),
            })
        }
        "yolov3-tiny" | "yolov8-320n" => {
            let file = if case.name == "yolov3-tiny" {
                aeris_models::detect::COCO_DETECTOR
            } else {
                aeris_models::detect::YOLOV8_DETECTOR
            };
            let (rgb, width, height) = load_rgb(store, "assets/bus.jpg")?;
            Box::new(DetectorProbe {
                detector: aeris_models::Detector::load(store, file, on)?,
                rgb,
                width,
                height,
                out: Vec::new(),
            })
        }
        "minilm" => {
            let mut texts: Vec<String> = mission.subgoals.iter().map(|s| s.text.clone()).collect();
            texts.extend(
                ["LAKE VIEW", "yellow sign", "red roof", "blue water tower"].map(String::from),
            );
            Box::new(EmbedProbe {
                embedder: TextEmbedder::load(store, on)?,
                texts,
                out: Vec::new(),
            })
        }
        "smollm2" | "gemma3" => {
            let file = if case.name == "smollm2" {
                aeris_llm::SMOLLM2_135M
            } else {
                aeris_llm::GEMMA3_270M
            };
            let config = ReasonerConfig {
                threads: threads as i32,
                accelerator: on.accelerator,
                ..ReasonerConfig::default()
            };
            let brief = aeris_roles::language::mission_brief(mission)?;
            let planner = Planner::new(mission, &aeris_runtime::spec::CameraSpec::default())
                .ok_or_else(|| BenchError::Config("the mission names an unknown action".into()))?;
            Box::new(LlmProbe {
                reasoner: LanguageReasoner::load(store, file, brief, config)?,
                fresh: planner.clone(),
                planner,
                states: (0..PATH.len()).map(sample_state).collect(),
                previous: None,
                last: None,
            })
        }
        other => return Err(BenchError::Config(format!("unknown model `{other}`"))),
    })
}

/// Measure one model in this process: load (its sessions or layers on `on`'s accelerator, if
/// it names one), one warm-up run, `runs` timed runs.
pub fn probe(
    case: &ModelCase,
    store: &ModelStore,
    on: &SessionOptions,
    runs: usize,
    mission: &MissionSpec,
) -> Result<ModelRow, BenchError> {
    let runs = runs.max(1);
    let bare = rss_mib();
    let t0 = Instant::now();
    let mut p = load_probe(case, store, on, mission)?;
    let load_s = t0.elapsed().as_secs_f64();
    p.run(0)?;
    let mut ms = Vec::with_capacity(runs);
    let (mut tps, mut prompt, mut generated) = (0.0, 0usize, 0usize);
    let mut output = String::new();
    for i in 1..=runs {
        let t = Instant::now();
        output = p.run(i)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
        if let Some((a, b, c)) = p.llm_figures() {
            tps += a;
            prompt += b;
            generated += c;
        }
    }
    let rss = rss_mib();
    let pct = |q| aeris_runtime::stats::percentile(&ms, q).unwrap_or(0.0);
    let llm = p.llm_figures().is_some();
    let mean = |x: f64| llm.then_some(x / runs as f64);
    Ok(ModelRow {
        model: case.name.into(),
        role: case.role.into(),
        runtime: case.runtime.into(),
        input: case.input.into(),
        load_s,
        runs,
        p50_ms: pct(50.0),
        p95_ms: pct(95.0),
        rss_mib: rss,
        rss_model_mib: (rss - bare).max(0.0),
        tokens_per_s: mean(tps),
        prompt_tokens_new: mean(prompt as f64),
        generated_tokens: mean(generated as f64),
        output,
    })
}
