//! The provisioned model cache and its sha256 manifest.

use crate::error::ModelError;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Environment variable that overrides the cache folder.
pub const MODELS_ENV: &str = "AERIS_MODELS";
/// Manifest file name inside the cache.
pub const MANIFEST: &str = "MANIFEST.sha256";

/// The model cache: a folder and the sha256 of every file in it.
#[derive(Debug, Clone)]
pub struct ModelStore {
    root: PathBuf,
    manifest: BTreeMap<String, String>,
}

/// The default cache folder: `$AERIS_MODELS`, else `$HOME/.cache/aeris/models`.
pub fn default_root() -> PathBuf {
    if let Some(p) = std::env::var_os(MODELS_ENV).filter(|p| !p.is_empty()) {
        return PathBuf::from(p);
    }
    let home = std::env::var_os("HOME").map_or_else(|| PathBuf::from("/"), PathBuf::from);
    home.join(".cache").join("aeris").join("models")
}

/// sha256 of a file, lower-case hex.
pub fn sha256_file(path: &Path) -> Result<String, ModelError> {
    let io = |source| ModelError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = file.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

impl ModelStore {
    /// Open the cache at `root` (or [`default_root`]) and read its manifest.
    pub fn open(root: Option<&Path>) -> Result<Self, ModelError> {
        let root = root.map_or_else(default_root, Path::to_path_buf);
        let path = root.join(MANIFEST);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(ModelError::NotProvisioned { root });
            }
            Err(e) => {
                return Err(ModelError::Manifest {
                    path,
                    reason: e.to_string(),
                });
            }
        };
        let mut manifest = BTreeMap::new();
        for (n, line) in text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
        {
            let bad = |reason: &str| ModelError::Manifest {
                path: path.clone(),
                reason: format!("line {}: {reason}", n + 1),
            };
            let (hash, file) = line
                .split_once("  ")
                .ok_or_else(|| bad("expected `SHA256  PATH`"))?;
            if hash.len() != 64 || !hash.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(bad("not a sha256"));
            }
            if file.starts_with('/') || file.split('/').any(|c| c == "..") {
                return Err(bad("path leaves the cache"));
            }
            manifest.insert(file.to_string(), hash.to_ascii_lowercase());
        }
        Ok(Self { root, manifest })
    }

    /// The cache folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Files the manifest lists (paths relative to the cache).
    pub fn files(&self) -> impl Iterator<Item = &str> {
        self.manifest.keys().map(String::as_str)
    }

    /// Path of `file` (relative to the cache) after checking it exists and its sha256
    /// matches the manifest.
    pub fn verified(&self, file: &str) -> Result<PathBuf, ModelError> {
        let expected = self.manifest.get(file).ok_or_else(|| ModelError::Unknown {
            file: file.to_string(),
            root: self.root.clone(),
        })?;
        let path = self.root.join(file);
        if !path.is_file() {
            return Err(ModelError::Missing { path });
        }
        let actual = sha256_file(&path)?;
        if &actual != expected {
            return Err(ModelError::Corrupt {
                path,
                expected: expected.clone(),
                actual,
            });
        }
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cache folder with an empty `m/` that is removed when the guard drops.
    fn temp_cache(tag: &str) -> tempfile::TempDir {
        let dir = tempfile::Builder::new()
            .prefix(&format!("aeris-store-{tag}-"))
            .tempdir()
            .unwrap();
        std::fs::create_dir_all(dir.path().join("m")).unwrap();
        dir
    }

    #[test]
    fn a_missing_cache_names_the_provisioning_command() {
        let guard = temp_cache("missing");
        let dir = guard.path();
        let err = ModelStore::open(Some(dir)).unwrap_err();
        assert!(matches!(err, ModelError::NotProvisioned { .. }));
        assert!(
            err.to_string().contains("scripts/provision-models.sh"),
            "{err}"
        );
    }

    #[test]
    fn verifies_files_against_the_manifest() {
        let guard = temp_cache("verify");
        let dir = guard.path();
        std::fs::write(dir.join("m/a.onnx"), b"model bytes").unwrap();
        let good = sha256_file(&dir.join("m/a.onnx")).unwrap();
        std::fs::write(
            dir.join(MANIFEST),
            format!("{good}  m/a.onnx\n{good}  m/gone.onnx\n"),
        )
        .unwrap();
        let store = ModelStore::open(Some(dir)).unwrap();
        assert_eq!(store.verified("m/a.onnx").unwrap(), dir.join("m/a.onnx"));
        assert!(matches!(
            store.verified("m/gone.onnx"),
            Err(ModelError::Missing { .. })
        ));
        assert!(matches!(
            store.verified("m/other.onnx"),
            Err(ModelError::Unknown { .. })
        ));
        // one flipped byte: refused, and the message says how to fix it
        std::fs::write(dir.join("m/a.onnx"), b"model bytez").unwrap();
        let err = store.verified("m/a.onnx").unwrap_err();
        assert!(matches!(err, ModelError::Corrupt { .. }));
        assert!(
            err.to_string().contains("corrupt") && err.to_string().contains("provision-models")
        );
    }

    #[test]
    fn a_malformed_manifest_is_an_error_not_a_panic() {
        for text in [
            "nonsense\n",
            "abc  m/a.onnx\n",
            &format!("{}  ../etc/passwd\n", "0".repeat(64)),
        ] {
            let guard = temp_cache("malformed");
            let dir = guard.path();
            std::fs::write(dir.join(MANIFEST), text).unwrap();
            assert!(
                matches!(
                    ModelStore::open(Some(dir)),
                    Err(ModelError::Manifest { .. })
                ),
                "{text}"
            );
        }
    }
}
