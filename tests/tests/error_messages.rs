//! Every kind of bad input gives an error that says each thing once: the binary prints the
//! error chain (`aeris: error: what failed: why: root cause`) and no clause of it, nor the
//! offending file or name, appears twice. A library error whose message repeated its
//! `#[source]` printed `workflow file bad.toml: TOML syntax error ...: TOML syntax error ...`.

use aeris_tests::*;
use std::path::Path;
use std::process::Command;

/// One bad input: the arguments, extra environment, and the offender the error must name
/// exactly once.
struct Case {
    what: &'static str,
    args: Vec<String>,
    env: Vec<(&'static str, String)>,
    offender: String,
}

fn case(what: &'static str, args: &[&str], offender: &str) -> Case {
    Case {
        what,
        args: args.iter().map(|s| s.to_string()).collect(),
        env: Vec::new(),
        offender: offender.to_string(),
    }
}

fn path_str(p: &Path) -> String {
    p.to_str().expect("utf-8 temp path").to_string()
}

/// The clauses of an error line: the text after `aeris: error:` split at `: `.
fn clauses(line: &str) -> Vec<&str> {
    let text = line.split_once("error:").map_or(line, |(_, rest)| rest);
    text.split(": ")
        .map(str::trim)
        .filter(|c| !c.is_empty())
        .collect()
}

/// The first clause that appears twice, ignoring case and surrounding punctuation.
fn repeated_clause(line: &str) -> Option<String> {
    let all: Vec<String> = clauses(line)
        .iter()
        .map(|c| c.trim_matches(|ch: char| ch.is_ascii_punctuation() || ch.is_whitespace()))
        .map(str::to_lowercase)
        .collect();
    all.iter()
        .enumerate()
        .find(|(i, c)| all[..*i].contains(c))
        .map(|(_, c)| c.clone())
}

#[test]
fn clause_splitting_finds_a_repeated_source() {
    // the defect this test guards against, as `aeris validate` printed it
    let line = "aeris: error: workflow file bad.toml: TOML syntax error at line 1, column 12: \
                unclosed array: TOML syntax error at line 1, column 12: unclosed array";
    assert_eq!(
        repeated_clause(line).as_deref(),
        Some("toml syntax error at line 1, column 12")
    );
    assert_eq!(
        repeated_clause("aeris: error: workflow bad.toml: unknown variant `x`"),
        None
    );
}

#[test]
fn every_kind_of_bad_input_names_its_offender_once() {
    let dir = TempDir::new("error-messages");
    let d = &dir.0;

    // workflows: TOML syntax, an unknown variant, a bad CPU list, a missing file
    let syntax = d.join("syntax.toml");
    std::fs::write(&syntax, "roles = [\n").expect("write");
    let mut w = default_workflow();
    set_variant(&mut w, "reasoning", "gpt-9");
    let variant = write_workflow(d, "variant", &w);
    let mut w = default_workflow();
    w["executors"]["control"]["cpus"] = toml::Value::String("0-x".into());
    let cpus = write_workflow(d, "cpus", &w);
    let missing_workflow = d.join("no-such-workflow.toml");
    // another host at an endpoint that is not zenoh's TCP
    let mut w = default_workflow();
    let host: toml::Table = "endpoint = \"udp/10.0.0.2:7447\"".parse().unwrap();
    let mut hosts = toml::Table::new();
    hosts.insert("ground".into(), toml::Value::Table(host));
    w.insert("hosts".into(), toml::Value::Table(hosts));
    let endpoint = write_workflow(d, "endpoint", &w);
    // another host over TLS whose keys are not there
    let missing_keys = d.join("no-such-keys");
    let mut w = default_workflow();
    let host: toml::Table = format!(
        "endpoint = \"tls/10.0.0.2:7447\"\nkeys = \"{}\"",
        missing_keys.display()
    )
    .parse()
    .unwrap();
    let mut hosts = toml::Table::new();
    hosts.insert("ground".into(), toml::Value::Table(host));
    w.insert("hosts".into(), toml::Value::Table(hosts));
    let host_keys = write_workflow(d, "host-keys", &w);
    // a flight of more vehicles than a flight may have
    let mut w = default_workflow();
    let vehicles = |w: &mut toml::Table, n: i64| {
        w["flight"]
            .as_table_mut()
            .expect("[flight]")
            .insert("vehicles".into(), toml::Value::Integer(n));
    };
    vehicles(&mut w, 9);
    let fleet = write_workflow(d, "fleet", &w);
    // several vehicles, but one vehicle role and one controller for all of them
    let mut w = default_workflow();
    vehicles(&mut w, 2);
    let formation: toml::Table = "name = \"formation\"\nkind = \"formation\"\nvariant = \"parser\""
        .parse()
        .unwrap();
    w["roles"]
        .as_array_mut()
        .expect("roles")
        .push(toml::Value::Table(formation));
    let shared_controller = write_workflow(d, "shared-controller", &w);

    // episode files: JSON syntax, a missing field, a missing file
    let episodes_syntax = d.join("episodes-syntax.json");
    std::fs::write(&episodes_syntax, "{\"episodes\": [\n").expect("write");
    let episodes_field = d.join("episodes-field.json");
    std::fs::write(&episodes_field, "{\"episodes\": [{\"episode_id\": 3}]}").expect("write");
    let missing_episodes = d.join("no-such-episodes.json");

    // models: a cache without a manifest, and one whose files are missing
    let no_cache = d.join("no-model-cache");
    std::fs::create_dir_all(&no_cache).expect("mkdir");
    let hollow_cache = d.join("hollow-model-cache");
    std::fs::create_dir_all(&hollow_cache).expect("mkdir");
    std::fs::write(
        hollow_cache.join("MANIFEST.sha256"),
        format!("{}  llm/smollm2-135m-instruct-q8_0.gguf\n", "0".repeat(64)),
    )
    .expect("write manifest");

    let mut cases = Vec::new();
    for cmd in ["validate", "run"] {
        cases.push(case(
            "TOML syntax",
            &[cmd, &path_str(&syntax)],
            &path_str(&syntax),
        ));
        cases.push(case(
            "unknown variant",
            &[cmd, &path_str(&variant)],
            "gpt-9",
        ));
        cases.push(case("bad CPU list", &[cmd, &path_str(&cpus)], "0-x"));
        cases.push(case(
            "too many vehicles",
            &[cmd, &path_str(&fleet)],
            "vehicles = 9",
        ));
        cases.push(case(
            "a vehicle role for several vehicles",
            &[cmd, &path_str(&shared_controller)],
            "`vehicle`",
        ));
        cases.push(case(
            "bad host endpoint",
            &[cmd, &path_str(&endpoint)],
            "udp/10.0.0.2:7447",
        ));
        cases.push(case(
            "missing workflow",
            &[cmd, &path_str(&missing_workflow)],
            &path_str(&missing_workflow),
        ));
    }
    for file in [&episodes_syntax, &episodes_field, &missing_episodes] {
        let f = path_str(file);
        cases.push(case("episode file", &["episodes", "check", &f], &f));
        cases.push(case(
            "episode file",
            &["eval", "--episodes-file", &f, "--episodes", "1"],
            &f,
        ));
    }
    cases.push(case(
        "keys of a host's link",
        &["run", &path_str(&host_keys)],
        &path_str(&missing_keys),
    ));
    cases.push(case(
        "agent endpoint",
        &[
            "agent",
            "--host",
            "ground",
            "--insecure",
            "--listen",
            "udp/0.0.0.0:7447",
        ],
        "udp/0.0.0.0:7447",
    ));
    let no_keys = d.join("no-keys");
    cases.push(case(
        "agent keys",
        &[
            "agent",
            "--host",
            "ground",
            "--keys",
            &path_str(&no_keys),
            "--flight-host",
            "vehicle",
        ],
        &path_str(&no_keys),
    ));
    let no_ca = d.join("no-ca");
    cases.push(case(
        "key store without a CA",
        &["keys", "issue", &path_str(&no_ca), "ground"],
        &path_str(&no_ca),
    ));
    cases.push(case(
        "host name of a certificate",
        &["keys", "issue", &path_str(&no_ca), "../ground"],
        "../ground",
    ));
    cases.push(case(
        "formation say to no flight",
        &[
            "formation",
            "say",
            "--flight",
            "no-such-formation",
            "form a line",
        ],
        "no-such-formation",
    ));
    cases.push(case(
        "--variant argument",
        &["run", "--variant", "reasoning"],
        "reasoning",
    ));
    cases.push(case(
        "--max-duration argument",
        &["run", "--max-duration", "nan"],
        "--max-duration",
    ));
    cases.push(case(
        "--run-dir argument",
        &["run", "--run-dir", "/proc/aeris-no-such-dir"],
        "/proc/aeris-no-such-dir",
    ));
    cases.push(case(
        "unwritable video file",
        &[
            "scene",
            "video",
            "village",
            "--path",
            "0,0,12",
            "--hold",
            "1",
            "--out",
            "/proc/aeris-no-such-dir/v.mp4",
        ],
        "/proc/aeris-no-such-dir/v.mp4",
    ));
    cases.push(case(
        "--udp argument",
        &[
            "scene",
            "video",
            "village",
            "--path",
            "0,0,12",
            "--udp",
            "localhost:99999",
        ],
        "localhost:99999",
    ));
    cases.push(case(
        "--path argument",
        &[
            "scene", "video", "village", "--path", "0,x,12", "--out", "v.mp4",
        ],
        "0,x,12",
    ));
    for cache in [&no_cache, &hollow_cache] {
        cases.push(Case {
            what: "missing model",
            args: ["bench", "models", "--only", "smollm2", "--runs", "1"]
                .iter()
                .map(|s| s.to_string())
                .collect(),
            env: vec![("AERIS_MODELS", path_str(cache))],
            offender: path_str(cache),
        });
    }

    let mut failures = Vec::new();
    for c in &cases {
        let out = Command::new(aeris_bin())
            .args(&c.args)
            .envs(c.env.iter().map(|(k, v)| (k, v)))
            .output()
            .expect("run aeris");
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        let label = format!("{} (aeris {})", c.what, c.args.join(" "));
        if out.status.success() {
            failures.push(format!("{label}: exited 0:\n{text}"));
            continue;
        }
        if text.contains("panicked") {
            failures.push(format!("{label}: panicked:\n{text}"));
            continue;
        }
        let errors: Vec<&str> = text.lines().filter(|l| l.contains("error")).collect();
        if errors.is_empty() {
            failures.push(format!("{label}: no error line:\n{text}"));
            continue;
        }
        let named = errors.iter().filter(|l| l.contains(&c.offender)).count();
        if named == 0 {
            failures.push(format!("{label}: `{}` not named:\n{text}", c.offender));
        }
        for line in &errors {
            if let Some(clause) = repeated_clause(line) {
                failures.push(format!("{label}: clause `{clause}` twice in:\n  {line}"));
            }
            let times = line.matches(c.offender.as_str()).count();
            if times > 1 {
                failures.push(format!(
                    "{label}: `{}` named {times} times in:\n  {line}",
                    c.offender
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} bad inputs gave errors that repeat themselves:\n\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n\n")
    );
}
