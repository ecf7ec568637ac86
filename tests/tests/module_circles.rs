//! No two files of a crate use each other, directly or around a circle: a file's module
//! names what it builds on (`use crate::...`, `use super::...`), and what it builds on
//! does not reach back to it. A circle is one concept in two files, or a type in the wrong
//! one (an error or a shared type belongs in a file of its own, as iceoryx2 does it).
//! Tests (`#[cfg(test)]` and after) and comments are not read.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module a file is, as a path from the crate root (`supervisor::swap`; the root is "").
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap_or(file).with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts
        .last()
        .is_some_and(|l| l == "mod" || l == "lib" || l == "main")
    {
        parts.pop();
    }
    parts.join("::")
}

/// The code a file builds on: up to its tests, without comment lines.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The `a::b::c` paths after each `prefix` in `code`.
fn paths_after<'a>(code: &'a str, prefix: &'a str) -> impl Iterator<Item = Vec<&'a str>> + 'a {
    code.match_indices(prefix).filter_map(move |(i, _)| {
        let before = code[..i].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            return None;
        }
        let rest = &code[i + prefix.len()..];
        let mut parts = Vec::new();
        let mut s = rest;
        loop {
            let end = s
                .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'))
                .unwrap_or(s.len());
            if end == 0 {
                break;
            }
            parts.push(&s[..end]);
            match s[end..].strip_prefix("::") {
                Some(next) => s = next,
                None => break,
            }
        }
        (!parts.is_empty()).then_some(parts)
    })
}

/// The modules each module of the crate at `src` uses (not its own ancestors or
/// descendants).
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeMap<String, PathBuf> = files
        .iter()
        .map(|f| (module_of(src, f), f.clone()))
        .collect();
    let mut graph = BTreeMap::new();
    for (m, file) in &modules {
        let text = code(&std::fs::read_to_string(file).unwrap_or_default());
        let parent: Vec<&str> = m.split("::").filter(|s| !s.is_empty()).collect();
        let parent = &parent[..parent.len().saturating_sub(1)];
        let mut uses = BTreeSet::new();
        let refs = paths_after(&text, "crate::").chain(paths_after(&text, "super::").map(|p| {
            let mut full: Vec<&str> = parent.to_vec();
            full.extend(p);
            full
        }));
        for parts in refs {
            let Some(target) = (1..=parts.len())
                .rev()
                .map(|k| parts[..k].join("::"))
                .find(|c| modules.contains_key(c))
            else {
                continue;
            };
            let related = target == *m
                || m.starts_with(&format!("{target}::"))
                || target.starts_with(&format!("{m}::"));
            if !related {
                uses.insert(target);
            }
        }
        graph.insert(m.clone(), uses);
    }
    graph
}

/// The modules `from` reaches by uses.
fn reach(graph: &BTreeMap<String, BTreeSet<String>>, from: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut stack = vec![from.to_string()];
    while let Some(m) = stack.pop() {
        for n in graph.get(&m).into_iter().flatten() {
            if seen.insert(n.clone()) {
                stack.push(n.clone());
            }
        }
    }
    seen
}

#[test]
fn no_file_of_a_crate_reaches_back_to_a_file_that_uses_it() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate sits in the workspace");
    let mut circles = Vec::new();
    let mut crates = 0;
    for entry in std::fs::read_dir(root).expect("the workspace").flatten() {
        let src = entry.path().join("src");
        if !entry.path().join("Cargo.toml").is_file() || !src.is_dir() {
            continue;
        }
        crates += 1;
        let graph = module_graph(&src);
        for (m, uses) in &graph {
            for n in uses {
                if m < n && reach(&graph, n).contains(m) {
                    circles.push(format!(
                        "{}: `{m}` and `{n}`",
                        entry.file_name().to_string_lossy()
                    ));
                }
            }
        }
    }
    assert!(crates >= 10, "found only {crates} crates under {root:?}");
    assert!(
        circles.is_empty(),
        "files that reach back to each other:\n{}",
        circles.join("\n")
    );
}

#[test]
fn a_circle_is_found_where_one_is() {
    // the check itself, on a scratch crate
    let dir = std::env::temp_dir().join(format!("aeris-circles-{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(src.join("a")).expect("scratch crate");
    let write = |p: &str, t: &str| std::fs::write(src.join(p), t).expect("scratch file");
    write("lib.rs", "mod a;\nmod b;\nmod c;\nmod d;\nmod e;\n");
    write("a/mod.rs", "mod inner;\nuse crate::b::Thing;\n");
    write("a/inner.rs", "use super::Thing;\n// use crate::b::Y;\n");
    write("b.rs", "use crate::a::inner::Other;\n");
    write(
        "c.rs",
        "use crate::b::X;\n#[cfg(test)]\nmod tests { use crate::a::Z; }\n",
    );
    write("d.rs", "pub use crate::e::E;\n");
    write("e.rs", "fn f() -> super::d::D { todo!() }\n");
    let graph = module_graph(&src);
    let _ = std::fs::remove_dir_all(&dir);
    let set = |names: &[&str]| names.iter().map(|n| n.to_string()).collect::<BTreeSet<_>>();
    assert_eq!(graph["a"], set(&["b"]));
    // its parent, a comment: nothing
    assert_eq!(graph["a::inner"], set(&[]));
    assert_eq!(graph["b"], set(&["a::inner"]));
    // a test names nothing
    assert_eq!(graph["c"], set(&["b"]));
    assert!(!reach(&graph, "a").contains("a"));
    // `super::` from a top-level file is the crate root
    assert_eq!(graph["e"], set(&["d"]));
    assert!(reach(&graph, "d").contains("d"));
}
