//! The check the `spawn_admission` fuzz target and its corpus replay share: whatever bytes
//! reach an agent as a `spawn` request, an admitted request names only files under the
//! agent's run directory, runs a kind on its allow-list, and carries no parameter from the
//! network that names a file, model, pipeline or endpoint.

use crate::admission::{
    AgentPolicy, AllowList, BRIDGE_CONNECT_PARAM, BRIDGE_KEYS_PARAM, LocalLink, NETWORK_PARAMS,
    OwnParam, admit, read_request,
};
use aeris_runtime::affinity::CpuSet;
use aeris_schemas::RoleKind;
use std::path::{Component, Path};

/// The run directory the check admits against.
pub const FUZZ_RUN_DIR: &str = "/var/lib/aeris-agent/ground";

/// The agent policy of the check: the default allow-list, one parameter of the agent's own,
/// a TLS link with keys.
pub fn fuzz_policy() -> AgentPolicy {
    AgentPolicy {
        host: "ground".into(),
        allow: AllowList::default_remote(),
        own_params: vec![OwnParam {
            kind: "reasoning".into(),
            variant: Some("smollm2".into()),
            key: "model".into(),
            value: "/opt/aeris/smollm2.gguf".into(),
        }],
        link: LocalLink {
            connect: "tls/127.0.0.1:7447".into(),
            keys: Some("/etc/aeris/keys/ground".into()),
        },
        online: CpuSet::parse("0-3").unwrap_or_else(|_| CpuSet::available()),
    }
}

/// `true` when `path` lies under `base` by plain components only.
fn plainly_under(path: &Path, base: &Path) -> bool {
    path.strip_prefix(base).is_ok_and(|rest| {
        rest.components().count() >= 1
            && rest.components().all(|c| matches!(c, Component::Normal(_)))
    })
}

/// [`fuzz_check_spawn`], and an admitted request's files written the way the agent writes
/// them under the private directory `run_dir`: they resolve under it.
pub fn fuzz_check_spawn_on_disk(bytes: &[u8], run_dir: &Path) {
    let Some(a) = fuzz_check_spawn(bytes) else {
        return;
    };
    let (spec, log) = crate::agent::write_role_files(run_dir, &a)
        .unwrap_or_else(|e| panic!("an admitted request's files: {e}"));
    let root = std::fs::canonicalize(run_dir).expect("the run directory");
    let written = std::fs::canonicalize(&spec).expect("the written spec");
    assert!(written.starts_with(&root), "{}", written.display());
    assert!(log.starts_with(run_dir), "{}", log.display());
}

/// Admit `bytes` as a spawn request; panics when an admitted request breaks the
/// properties above (a refusal is always fine). The admission, if any.
pub fn fuzz_check_spawn(bytes: &[u8]) -> Option<crate::admission::Admission> {
    let policy = fuzz_policy();
    let req = read_request(bytes).ok()?;
    let asked: Vec<String> = req.spec.params.keys().cloned().collect();
    let a = admit(req, &policy).ok()?;
    let run_dir = Path::new(FUZZ_RUN_DIR);
    for p in [a.spec_path(run_dir), a.log_path(run_dir)] {
        assert!(
            plainly_under(&p, run_dir),
            "{} is not under {FUZZ_RUN_DIR}",
            p.display()
        );
        assert_eq!(
            p.components().count(),
            run_dir.components().count() + 3,
            "{}",
            p.display()
        );
    }
    assert!(
        policy.allow.allows(a.spec.kind, &a.spec.variant),
        "{}/{} admitted",
        a.spec.kind,
        a.spec.variant
    );
    for k in &asked {
        assert!(
            NETWORK_PARAMS.contains(&k.as_str()),
            "param `{k}` from the network admitted"
        );
    }
    for (k, v) in &a.spec.params {
        let own = policy
            .own_params
            .iter()
            .any(|p| &p.key == k && &p.value == v);
        let link = a.spec.kind == RoleKind::Bridge
            && ((k == BRIDGE_CONNECT_PARAM && v == policy.link.connect.as_str())
                || (k == BRIDGE_KEYS_PARAM
                    && policy
                        .link
                        .keys
                        .as_ref()
                        .is_some_and(|d| v == d.display().to_string().as_str())));
        assert!(
            own || link || (NETWORK_PARAMS.contains(&k.as_str()) && asked.contains(k)),
            "param `{k}` = {v} admitted"
        );
    }
    assert!(a.spec.remote.is_none());
    Some(a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_check_passes_a_plain_request_and_refusals() {
        let req = serde_json::json!({
            "schema": crate::protocol::SchemaStamp::current(),
            "spec": {"flight": "f", "name": "bridge-on-ground", "kind": "bridge",
                     "variant": "zenoh", "params": {"import": [], "connect": "tls/evil:1"},
                     "mission": {"instruction": "x", "subgoals": []}},
            "handle_pid": 1,
        });
        assert!(fuzz_check_spawn(req.to_string().as_bytes()).is_none());
        assert!(fuzz_check_spawn(b"{").is_none());
        assert!(fuzz_check_spawn(&[0xff; 64]).is_none());
    }
}
