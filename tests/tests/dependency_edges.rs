//! The simulator stays at the edge: the flight roles (the controller among them), the hub
//! and the MAVLink crate build without `aeris-sim`, and the geometry leaf needs no crate of
//! ours. Asked of cargo itself (`cargo tree -e normal`: what a build of the crate compiles,
//! dev-dependencies left out), so a dependency that comes back through any path, a new
//! crate in between included, fails here. A vehicle build of the `aeris` binary (without its
//! default `sim` feature) compiles no simulator either, and the binary holds no flight loop.
//! ARCHITECTURE.md's crate table names exactly each crate's dependencies of ours
//! (`cargo metadata`), so the table cannot drift from the manifests again.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

/// Every package `package` compiles in a normal build (itself included), by name.
fn normal_dependencies(package: &str) -> BTreeSet<String> {
    dependencies_with(package, &[])
}

/// What `cargo ARGS` prints, run offline and locked in the workspace.
fn cargo_stdout(args: &[&str]) -> Vec<u8> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = Command::new(&cargo)
        .current_dir(&workspace)
        .args(args)
        .args(["--offline", "--locked"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run `{cargo} {}`: {e}", args.join(" ")));
    assert!(
        out.status.success(),
        "`cargo {}` failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// As [`normal_dependencies`], with extra `cargo tree` arguments (features).
fn dependencies_with(package: &str, extra: &[&str]) -> BTreeSet<String> {
    let mut args = vec!["tree", "-e", "normal", "-p", package];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--prefix", "none", "--format", "{p}"]);
    let out = cargo_stdout(&args);
    let names: BTreeSet<String> = String::from_utf8_lossy(&out)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect();
    assert!(
        names.contains(package),
        "`cargo tree -p {package}` does not list {package} itself: {names:?}"
    );
    names
}

/// The crates of this workspace among `names`, but `package` itself.
fn ours(names: &BTreeSet<String>, package: &str) -> BTreeSet<String> {
    names
        .iter()
        .filter(|n| n.starts_with("aeris") && *n != package)
        .cloned()
        .collect()
}

#[test]
fn the_flight_roles_and_the_hub_build_without_the_simulator() {
    for package in ["aeris-roles", "aeris-hub", "aeris-mavlink"] {
        let deps = normal_dependencies(package);
        assert!(
            !deps.contains("aeris-sim") && !deps.contains("aeris-sim-roles"),
            "{package} depends on the simulator again: {:?}",
            ours(&deps, package)
        );
    }
    // not vacuous: the tree is the real one
    let roles = normal_dependencies("aeris-roles");
    for dep in [
        "aeris-runtime",
        "aeris-mavlink",
        "aeris-geometry",
        "mavlink",
    ] {
        assert!(roles.contains(dep), "aeris-roles without {dep}: {roles:?}");
    }
    // and the simulator's roles are where the simulator is
    assert!(normal_dependencies("aeris-sim-roles").contains("aeris-sim"));
}

#[test]
fn geometry_and_the_mavlink_link_depend_on_no_crate_of_ours() {
    for package in ["aeris-geometry", "aeris-mavlink"] {
        let deps = normal_dependencies(package);
        assert_eq!(ours(&deps, package), BTreeSet::new(), "{package}");
    }
}

#[test]
fn a_vehicle_build_of_the_binary_compiles_no_simulator() {
    let vehicle = dependencies_with("aeris", &["--no-default-features"]);
    for sim in ["aeris-sim", "aeris-sim-roles", "aeris-eval"] {
        assert!(
            !vehicle.contains(sim),
            "aeris --no-default-features compiles {sim}: {:?}",
            ours(&vehicle, "aeris")
        );
    }
    // not vacuous: the default build has the simulator, the vehicle build the flight roles
    assert!(normal_dependencies("aeris").contains("aeris-sim"));
    for dep in ["aeris-roles", "aeris-hub", "aeris-flight", "aeris-mavlink"] {
        assert!(vehicle.contains(dep), "the vehicle build lacks {dep}");
    }
}

/// Words of `text` (identifier characters), in order.
fn identifiers(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty())
}

/// The binary parses, calls libraries and prints: the flight loop (the `Supervisor` it steps
/// and the `FlightMonitor` that reads hub reports) lives in `aeris-flight`, so no file of
/// `cli/src` names either type.
#[test]
fn the_binary_holds_no_supervisor_and_no_flight_monitor() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cli/src");
    let mut files = 0;
    let mut found = Vec::new();
    // every file of cli/src, its folders (`bench/`) included
    let mut paths = Vec::new();
    let mut folders = vec![dir];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).expect("a cli/src folder") {
            let path = entry.expect("dir entry").path();
            if path.is_dir() {
                folders.push(path);
            } else {
                paths.push(path);
            }
        }
    }
    for path in paths {
        if path.extension().is_none_or(|e| e != "rs") {
            continue;
        }
        files += 1;
        let text = std::fs::read_to_string(&path).expect("read a cli source file");
        // the flight's event that carries a supervisor event is printing, not the loop
        let text = text.replace("FlightEvent::Supervisor", "FlightEvent::");
        for word in identifiers(&text) {
            if matches!(word, "Supervisor" | "FlightMonitor" | "SupervisorOptions") {
                found.push(format!("{}: {word}", path.display()));
            }
        }
    }
    assert!(
        files >= 5,
        "cli/src has only {files} Rust files: wrong folder?"
    );
    assert!(
        found.is_empty(),
        "flight loop types in the binary: {found:?}"
    );
    // not vacuous: the words are found where the loop is
    let flight = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../flight/src/supervise.rs"),
    )
    .expect("flight/src/supervise.rs");
    assert!(identifiers(&flight).any(|w| w == "Supervisor"));
}

/// Each workspace crate's direct dependencies on crates of ours, from `cargo metadata`
/// (normal dependencies, optional ones included), by short name (`aeris-sim-roles` ->
/// `sim-roles`; the binary `aeris` -> `cli`, the tests -> `tests`).
fn direct_workspace_dependencies() -> std::collections::BTreeMap<String, BTreeSet<String>> {
    let out = cargo_stdout(&["metadata", "--no-deps", "--format-version", "1"]);
    let meta: serde_json::Value =
        serde_json::from_slice(&out).expect("`cargo metadata` prints JSON");
    let short = |name: &str| match name {
        "aeris" => "cli".to_string(),
        n => n.trim_start_matches("aeris-").to_string(),
    };
    let packages = meta["packages"].as_array().expect("packages");
    let ours: BTreeSet<String> = packages
        .iter()
        .filter_map(|p| p["name"].as_str())
        .map(str::to_string)
        .collect();
    packages
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .filter(|d| d["kind"].is_null())
                .filter_map(|d| d["name"].as_str())
                .filter(|n| ours.contains(*n))
                .map(short)
                .collect();
            (short(p["name"].as_str().expect("name")), deps)
        })
        .collect()
}

/// ARCHITECTURE.md's crate table says whom each crate depends on: its last column names
/// exactly the crates of ours that the crate's manifest does (notes in words around them
/// are allowed), and every crate of the workspace has a row.
#[test]
fn architecture_md_names_each_crates_dependencies_of_ours() {
    let actual = direct_workspace_dependencies();
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../ARCHITECTURE.md"))
            .expect("ARCHITECTURE.md");
    let mut rows = std::collections::BTreeMap::new();
    for line in text.lines().skip_while(|l| !l.starts_with("## Crates")) {
        if line.starts_with("## ") && !line.starts_with("## Crates") {
            break;
        }
        let cells: Vec<&str> = line.split(" | ").collect();
        let Some(name) = cells
            .first()
            .and_then(|c| c.trim_start_matches("| ").strip_prefix('`'))
            .and_then(|c| c.split_once("/`"))
            .map(|(dir, _)| dir.to_string())
        else {
            continue;
        };
        let said: BTreeSet<String> = cells
            .last()
            .map(|c| {
                c.split(|ch: char| !(ch.is_ascii_alphanumeric() || ch == '-'))
                    .filter(|w| actual.contains_key(*w))
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default();
        rows.insert(name, said);
    }
    let mut wrong = Vec::new();
    for (krate, deps) in &actual {
        match rows.get(krate) {
            None => wrong.push(format!("{krate}: no row")),
            Some(said) if said != deps => wrong.push(format!(
                "{krate}: the table says {said:?}, Cargo.toml {deps:?}"
            )),
            Some(_) => {}
        }
    }
    assert!(
        wrong.is_empty(),
        "ARCHITECTURE.md's crate table has drifted:\n{}",
        wrong.join("\n")
    );
}

/// The flight library composes the supervisor: it links no language-model engine (the
/// caller hands in the offload check, `aeris_llm::offload_check`), and the flight roles do
/// not link the recorder (the binary's role registry runs it).
#[test]
fn the_flight_links_no_llama_cpp_and_the_roles_no_recorder() {
    let flight = normal_dependencies("aeris-flight");
    for engine in ["aeris-llm", "llama-cpp-2", "llama-cpp-sys-2"] {
        assert!(!flight.contains(engine), "aeris-flight compiles {engine}");
    }
    let roles = normal_dependencies("aeris-roles");
    assert!(
        !roles.contains("aeris-record"),
        "aeris-roles compiles aeris-record"
    );
    // not vacuous: the binary links both
    let binary = normal_dependencies("aeris");
    assert!(binary.contains("llama-cpp-2") && binary.contains("aeris-record"));
}
