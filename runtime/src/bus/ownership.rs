//! Whose a flight's iceoryx2 services are. iceoryx2 0.10 creates its files owner-only but
//! never checks who owns a service it opens (iceoryx2#1810): another local user who creates
//! a flight's service first (or its directories) is joined silently — by root always, since
//! root passes every file mode, and by anyone once the squatter opens the modes. A flight
//! joins only what its own user made: the iceoryx2 directories must belong to this user or
//! root, and a service's static config file to this user; anything else is refused with
//! an error naming the owner, before a port is attached to it.

use super::BusError;
use crate::users::{effective_uid as euid, user_name};
use iceoryx2::config::Config;
use iceoryx2::prelude::{MessagingPattern, ServiceName};
use iceoryx2::service::Service;
use iceoryx2::service::ipc::Service as Ipc;
use iceoryx2::service::service_hash::ServiceHash;
use std::os::unix::fs::MetadataExt;
use std::path::PathBuf;

/// Refuse iceoryx2's directories (root, services, nodes) when one that exists belongs to a
/// user other than this process's or root.
pub(super) fn check_directories(config: &Config) -> Result<(), BusError> {
    let g = &config.global;
    let us = euid();
    for dir in [
        g.root_path().to_string(),
        g.service_dir().to_string(),
        g.node_dir().to_string(),
    ] {
        let path = PathBuf::from(dir);
        if let Ok(meta) = std::fs::symlink_metadata(&path)
            && meta.uid() != us
            && meta.uid() != 0
        {
            let allowed = if us == 0 {
                "root".to_string()
            } else {
                format!("{} or root", user_name(us))
            };
            return Err(BusError::ForeignDirectory {
                path,
                owner: user_name(meta.uid()),
                allowed,
            });
        }
    }
    Ok(())
}

/// The static config file of the service `hash`.
fn static_config_path(config: &Config, hash: &ServiceHash) -> PathBuf {
    let g = &config.global;
    PathBuf::from(g.service_dir().to_string()).join(format!(
        "{}{}{}",
        g.prefix,
        hash.as_str(),
        g.service.static_config_storage_suffix
    ))
}

/// Refuse the service `hash` (named `service`) when its static config exists and belongs
/// to another user.
fn check_hash(config: &Config, service: &str, hash: &ServiceHash) -> Result<(), BusError> {
    let path = static_config_path(config, hash);
    match std::fs::symlink_metadata(&path) {
        Ok(meta) if meta.uid() != euid() || meta.file_type().is_symlink() => {
            Err(BusError::ForeignService {
                service: service.to_string(),
                owner: user_name(meta.uid()),
                us: user_name(euid()),
            })
        }
        _ => Ok(()),
    }
}

/// Before opening: refuse `name` (`pattern`) if another user made it.
pub(super) fn check_before_open(
    config: &Config,
    name: &ServiceName,
    pattern: MessagingPattern,
) -> Result<(), BusError> {
    let hash = ServiceHash::new::<<Ipc as Service>::ServiceNameHasher>(name, pattern);
    check_hash(config, name.as_str(), &hash)
}

/// After opening: refuse the opened service if another user made it (it was made between
/// the check before and the open).
pub(super) fn check_opened(
    config: &Config,
    name: &str,
    hash: &ServiceHash,
) -> Result<(), BusError> {
    check_hash(config, name, hash)
}
