//! The build configuration never hands host-native CPU flags to a cross build: a binary
//! built for this machine's CPU may die of an illegal instruction on the board (issue 21).
//! Checked on the checked-in `.cargo/config.toml` and on what `scripts/build-aarch64.sh`
//! would run (`--dry-run`), without building anything.

use std::path::PathBuf;
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn rustflags(table: &toml::Table) -> Vec<String> {
    table
        .get("rustflags")
        .and_then(|f| f.as_array())
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn native_cpu_flags_are_set_for_the_host_target_only() {
    let text = std::fs::read_to_string(repo().join(".cargo/config.toml")).unwrap();
    let config: toml::Table = text.parse().unwrap();
    // `[build] rustflags` (and `RUSTFLAGS`) reach every target, a cross build's included
    let build = config.get("build").and_then(|b| b.as_table());
    assert!(
        build.is_none_or(|b| !rustflags(b).join(" ").contains("native")),
        "[build] rustflags must not carry target-cpu=native: {text}"
    );
    let targets = config["target"].as_table().expect("[target.*] tables");
    let mut native = Vec::new();
    for (key, table) in targets {
        let flags = rustflags(table.as_table().unwrap()).join(" ");
        if flags.contains("native") {
            native.push(key.clone());
        }
    }
    // exactly the x86_64 host target: no `cfg(...)` table, which could match aarch64 too
    assert_eq!(native, ["x86_64-unknown-linux-gnu"], "{text}");
}

#[test]
fn llama_cpp_is_built_without_amx_for_the_host_target_only() {
    let text = std::fs::read_to_string(repo().join(".cargo/config.toml")).unwrap();
    let config: toml::Table = text.parse().unwrap();
    let env = config["env"].as_table().expect("[env]");
    // ggml's AMX kernels died of SIGILL on an AMX machine: off for the host's C and C++
    for key in [
        "CFLAGS_x86_64_unknown_linux_gnu",
        "CXXFLAGS_x86_64_unknown_linux_gnu",
    ] {
        let flags = env[key].as_str().unwrap_or_default();
        for f in ["-mno-amx-tile", "-mno-amx-int8", "-mno-amx-bf16"] {
            assert!(flags.split_whitespace().any(|w| w == f), "{key}: {flags}");
        }
    }
    // never for every target: an aarch64 cross compiler refuses -mno-amx-*
    for key in ["CFLAGS", "CXXFLAGS", "TARGET_CFLAGS", "TARGET_CXXFLAGS"] {
        assert!(
            !env.contains_key(key),
            "{key} would reach a cross build: {text}"
        );
    }
}

fn dry_run(board: &str) -> String {
    let out = Command::new("bash")
        .arg(repo().join("scripts/build-aarch64.sh"))
        .args(["--dry-run", "--board", board])
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn the_aarch64_cross_build_takes_its_cpu_flags_from_the_board_profile() {
    for (board, wanted) in [("orin", Some("+dotprod")), ("generic", None)] {
        let plan = dry_run(board);
        let flags = plan
            .lines()
            .find_map(|l| l.strip_prefix("CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUSTFLAGS="))
            .unwrap_or_else(|| panic!("no aarch64 rustflags in the plan: {plan}"));
        assert!(!flags.contains("native"), "{board}: {flags}");
        // a target-cpu would reach llama.cpp's C++ compiler as `-march=CPU`, which gcc
        // refuses for a CPU name
        assert!(!flags.contains("target-cpu"), "{board}: {flags}");
        match wanted {
            Some(feature) => assert!(flags.contains(feature), "{board}: {flags}"),
            // Armv8-A: the target's own baseline, no flag at all
            None => assert!(flags.is_empty(), "{board}: {flags}"),
        }
        assert!(
            plan.lines().any(|l| l
                .starts_with("build: cargo build --release --target aarch64-unknown-linux-gnu")),
            "{plan}"
        );
    }
    let refused = |args: &[&str], env: Option<(&str, &str)>| {
        let mut cmd = Command::new("bash");
        cmd.arg(repo().join("scripts/build-aarch64.sh"))
            .arg("--dry-run")
            .args(args)
            .env_remove("RUSTFLAGS")
            .env_remove("CARGO_ENCODED_RUSTFLAGS");
        if let Some((k, v)) = env {
            cmd.env(k, v);
        }
        let out = cmd.output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{out:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(refused(&["--board", "pi"], None).contains("unknown board `pi`"));
    // RUSTFLAGS would replace the board's flags for the cross build too
    let err = refused(&[], Some(("RUSTFLAGS", "-C target-cpu=native")));
    assert!(err.contains("RUSTFLAGS is set"), "{err}");
}
