//! Directories only their owner can use: the agent's run directory, a key store. Another
//! local user must not be able to plant a file or a symlink where we write (a run directory
//! under `$TMPDIR`, which anyone can pre-create, is the classic trap), so a directory is
//! refused when any component of its path is a symlink, belongs to a user other than us or
//! root, or can be changed by others without the sticky bit (`/tmp` itself is fine: others
//! cannot move what we own inside it). What we create is created `0700`; the directory
//! itself must be ours, and is tightened to `0700` if it was wider.

use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::{Component, Path, PathBuf};

/// Why a private directory or a file in it could not be made or used.
#[derive(Debug, thiserror::Error)]
pub enum PrivateDirError {
    /// A component of the path is a symbolic link.
    #[error("{path} is a symbolic link: a private directory is reached without links")]
    Symlink {
        /// The component.
        path: PathBuf,
    },
    /// A component belongs to another user.
    #[error(
        "{path} belongs to {owner}, not to this process's user ({us}): another user could plant files there"
    )]
    Owner {
        /// The component.
        path: PathBuf,
        /// Its owner (`nobody (uid 65534)`).
        owner: String,
        /// Our user.
        us: String,
    },
    /// A component can be written by others (and is not sticky, as `/tmp` is).
    #[error("{path} can be written by other users (mode {mode:o}, no sticky bit)")]
    Writable {
        /// The component.
        path: PathBuf,
        /// Its mode.
        mode: u32,
    },
    /// A component is not a directory.
    #[error("{path} is not a directory")]
    NotADirectory {
        /// The component.
        path: PathBuf,
    },
    /// The path leaves its base (`..`, an absolute part, an empty name).
    #[error("`{name}` is not a plain name inside {base}")]
    Outside {
        /// The base directory.
        base: PathBuf,
        /// The name as given.
        name: String,
    },
    /// The file system refused.
    #[error("cannot {what} {path}")]
    Io {
        /// What was being done (`create`, `read`).
        what: &'static str,
        /// The path.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

fn io<'a>(
    what: &'static str,
    path: &'a Path,
) -> impl FnOnce(std::io::Error) -> PrivateDirError + 'a {
    move |source| PrivateDirError::Io {
        what,
        path: path.to_path_buf(),
        source,
    }
}

pub use aeris_runtime::users::{effective_uid as current_uid, user_name};

/// Check one existing component: no link, a directory, owned by us or root, not writable by
/// others unless sticky.
fn check_component(path: &Path, us: u32) -> Result<(), PrivateDirError> {
    let meta = std::fs::symlink_metadata(path).map_err(io("read", path))?;
    if meta.file_type().is_symlink() {
        return Err(PrivateDirError::Symlink {
            path: path.to_path_buf(),
        });
    }
    if !meta.is_dir() {
        return Err(PrivateDirError::NotADirectory {
            path: path.to_path_buf(),
        });
    }
    if meta.uid() != us && meta.uid() != 0 {
        return Err(PrivateDirError::Owner {
            path: path.to_path_buf(),
            owner: user_name(meta.uid()),
            us: user_name(us),
        });
    }
    let mode = meta.mode() & 0o7777;
    if mode & 0o022 != 0 && mode & 0o1000 == 0 {
        return Err(PrivateDirError::Writable {
            path: path.to_path_buf(),
            mode,
        });
    }
    Ok(())
}

/// Make `dir` (and what is missing above it) a private directory, or refuse it: see the
/// module's rules. Returns `dir` made absolute (relative to the current directory).
pub fn ensure_private_dir(dir: &Path) -> Result<PathBuf, PrivateDirError> {
    let abs = if dir.is_absolute() {
        dir.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(io("read the current directory of", dir))?
            .join(dir)
    };
    let us = current_uid();
    let mut at = PathBuf::from("/");
    for c in abs.components() {
        match c {
            Component::RootDir | Component::CurDir => continue,
            Component::Normal(name) => at.push(name),
            Component::ParentDir => {
                return Err(PrivateDirError::Outside {
                    base: abs.clone(),
                    name: "..".into(),
                });
            }
            Component::Prefix(_) => continue,
        }
        match std::fs::symlink_metadata(&at) {
            Ok(_) => check_component(&at, us)?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                std::fs::DirBuilder::new()
                    .mode(0o700)
                    .create(&at)
                    .or_else(|e| {
                        // made by someone else meanwhile: checked below like any other
                        if e.kind() == std::io::ErrorKind::AlreadyExists {
                            Ok(())
                        } else {
                            Err(e)
                        }
                    })
                    .map_err(io("create", &at))?;
                check_component(&at, us)?;
            }
            Err(e) => return Err(io("read", &at)(e)),
        }
    }
    let meta = std::fs::symlink_metadata(&abs).map_err(io("read", &abs))?;
    if meta.uid() != us {
        return Err(PrivateDirError::Owner {
            path: abs,
            owner: user_name(meta.uid()),
            us: user_name(us),
        });
    }
    if meta.mode() & 0o077 != 0 {
        std::fs::set_permissions(&abs, std::fs::Permissions::from_mode(0o700))
            .map_err(io("restrict the permissions of", &abs))?;
    }
    Ok(abs)
}

/// `true` when `name` is one plain path component: no separator, not `.` or `..`, not
/// empty, no NUL.
pub fn is_plain_name(name: &str) -> bool {
    !name.is_empty() && name != "." && name != ".." && !name.bytes().any(|b| b == b'/' || b == 0)
}

/// `base/name`, a private directory inside the private directory `base` (created `0700`
/// when missing; refused when it is a link or another's).
pub fn private_subdir(base: &Path, name: &str) -> Result<PathBuf, PrivateDirError> {
    if !is_plain_name(name) {
        return Err(PrivateDirError::Outside {
            base: base.to_path_buf(),
            name: name.to_string(),
        });
    }
    let dir = base.join(name);
    match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(io("create", &dir)(e)),
    }
    check_component(&dir, current_uid())?;
    let meta = std::fs::symlink_metadata(&dir).map_err(io("read", &dir))?;
    if meta.uid() != current_uid() {
        return Err(PrivateDirError::Owner {
            path: dir,
            owner: user_name(meta.uid()),
            us: user_name(current_uid()),
        });
    }
    Ok(dir)
}

/// How [`open_private_file`] opens a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileMode {
    /// Create it, or empty it if it exists.
    Replace,
    /// Create it, or append to it if it exists.
    Append,
    /// Create it; refuse if it exists.
    New,
}

/// Open `dir/name` for writing with mode `perm` (`0o600`, `0o644`): never through a
/// symlink (`O_NOFOLLOW`), `name` one plain component.
pub fn open_private_file(
    dir: &Path,
    name: &str,
    mode: FileMode,
    perm: u32,
) -> Result<std::fs::File, PrivateDirError> {
    if !is_plain_name(name) {
        return Err(PrivateDirError::Outside {
            base: dir.to_path_buf(),
            name: name.to_string(),
        });
    }
    let path = dir.join(name);
    let mut o = std::fs::OpenOptions::new();
    o.write(true)
        .mode(perm)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC);
    match mode {
        FileMode::Replace => o.create(true).truncate(true),
        FileMode::Append => o.create(true).append(true),
        FileMode::New => o.create_new(true),
    };
    o.open(&path).map_err(|source| {
        if source.raw_os_error() == Some(libc::ELOOP) {
            PrivateDirError::Symlink { path: path.clone() }
        } else {
            PrivateDirError::Io {
                what: "write",
                path: path.clone(),
                source,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_private_dir_is_made_owner_only_and_a_wider_one_of_ours_is_tightened() {
        let t = tempfile::tempdir().unwrap();
        let d = ensure_private_dir(&t.path().join("a/b")).unwrap();
        assert_eq!(
            std::fs::metadata(&d).unwrap().permissions().mode() & 0o777,
            0o700
        );
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o755)).unwrap();
        ensure_private_dir(&d).unwrap();
        assert_eq!(
            std::fs::metadata(&d).unwrap().permissions().mode() & 0o777,
            0o700
        );
    }

    #[test]
    fn a_symlink_anywhere_on_the_path_is_refused_by_name() {
        let t = tempfile::tempdir().unwrap();
        let real = t.path().join("real");
        std::fs::create_dir(&real).unwrap();
        let link = t.path().join("link");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        let e = ensure_private_dir(&link.join("run")).unwrap_err();
        assert!(
            matches!(&e, PrivateDirError::Symlink { path } if path == &link),
            "{e}"
        );
        // and a file link inside a private dir is not followed
        let d = ensure_private_dir(&real.join("run")).unwrap();
        std::os::unix::fs::symlink(t.path().join("victim"), d.join("x.json")).unwrap();
        let e = open_private_file(&d, "x.json", FileMode::Replace, 0o600).unwrap_err();
        assert!(matches!(e, PrivateDirError::Symlink { .. }), "{e}");
        assert!(!t.path().join("victim").exists());
    }

    #[test]
    fn a_directory_others_can_write_without_the_sticky_bit_is_refused() {
        let t = tempfile::tempdir().unwrap();
        let open = t.path().join("open");
        std::fs::create_dir(&open).unwrap();
        std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).unwrap();
        let e = ensure_private_dir(&open.join("run")).unwrap_err();
        assert!(matches!(e, PrivateDirError::Writable { .. }), "{e}");
        std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o1777)).unwrap();
        ensure_private_dir(&open.join("run")).unwrap();
    }

    #[test]
    fn names_that_leave_their_directory_are_refused() {
        let t = tempfile::tempdir().unwrap();
        for bad in ["", ".", "..", "a/b", "../x", "x\0y"] {
            assert!(!is_plain_name(bad), "{bad:?}");
            assert!(private_subdir(t.path(), bad).is_err(), "{bad:?}");
            assert!(open_private_file(t.path(), bad, FileMode::New, 0o600).is_err());
        }
    }
}
