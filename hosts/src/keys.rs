//! The flight's identities (`aeris keys`): a certificate authority of the flight, and one
//! X.509 certificate and key per host, signed by it, that the hosts' zenoh links
//! authenticate each other with (mutual TLS) and that the agents' access rules name.
//!
//! A key store `DIR` holds the CA (`ca.pem`, `ca.key`; the CA's key never leaves the machine
//! that makes keys) and a directory per host, `DIR/HOST/` (`ca.pem`, `cert.pem`,
//! `key.pem`): the identity that host is given (copy `DIR/ground` to the ground station as
//! its `--keys`). The certificate's common name is the host's name; its subject alternative
//! names are the host name, `localhost`, 127.0.0.1, ::1 and the addresses given when it was
//! issued, because a client checks that the agent it dials holds a certificate for the
//! address it dialled. Keys are ECDSA P-256, made and signed by `rcgen` on `ring`; private
//! keys are written `0600` in `0700` directories, never over a symlink.

use crate::private_dir::{FileMode, PrivateDirError, ensure_private_dir, open_private_file};
use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa,
    Issuer, KeyPair, KeyUsagePurpose, SanType,
};
use std::io::Write;
use std::net::IpAddr;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use x509_parser::prelude::{FromDer, X509Certificate};

/// The CA's certificate in a key store, and in every host's identity.
pub const CA_CERT_FILE: &str = "ca.pem";
/// The CA's private key (only in the key store).
pub const CA_KEY_FILE: &str = "ca.key";
/// A host's certificate in its identity directory.
pub const CERT_FILE: &str = "cert.pem";
/// A host's private key in its identity directory.
pub const KEY_FILE: &str = "key.pem";

/// Days a flight CA is valid by default.
pub const DEFAULT_CA_DAYS: u32 = 1825;
/// Days a host certificate is valid by default: short, so that a lost key stops working
/// soon without a revocation list (re-issue to rotate).
pub const DEFAULT_HOST_DAYS: u32 = 30;

/// Why keys could not be made.
#[derive(Debug, thiserror::Error)]
pub enum KeysError {
    /// The store already holds a CA (`init`), or the host already has an identity
    /// (`issue` without replacing).
    #[error("{path} exists already: {hint}")]
    Exists {
        /// The file.
        path: PathBuf,
        /// What to do.
        hint: &'static str,
    },
    /// The store holds no CA.
    #[error("{dir} holds no flight CA ({CA_CERT_FILE}, {CA_KEY_FILE}): make one there with `aeris keys init` first", dir = .dir.display())]
    NoCa {
        /// The store.
        dir: PathBuf,
    },
    /// A host name unusable as a certificate and key-expression name.
    #[error("host name `{0}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    HostName(String),
    /// An address that is neither an IP address nor a DNS name.
    #[error("`{0}` is neither an IP address nor a DNS name")]
    Address(String),
    /// A validity of 0 days, or past what X.509 can say.
    #[error("a validity of {0} days is out of range (1-36500)")]
    Days(u32),
    /// The CA's files could not be read back.
    #[error("cannot read the flight CA {path}: {reason}")]
    Ca {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// rcgen refused (key generation, signing).
    #[error("cannot {what}")]
    Make {
        /// What (`sign the certificate of host ground`).
        what: String,
        /// rcgen's error.
        #[source]
        source: rcgen::Error,
    },
    /// A directory or file could not be made privately.
    #[error(transparent)]
    Private(#[from] PrivateDirError),
    /// A file could not be written.
    #[error("cannot write {path}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// What `aeris keys init` made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaMade {
    /// The CA's certificate.
    pub cert: PathBuf,
    /// The CA's private key (`0600`).
    pub key: PathBuf,
    /// Valid until (UTC).
    pub not_after: String,
}

/// What `aeris keys issue` made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Issued {
    /// The host's identity directory (copy it to the host).
    pub dir: PathBuf,
    /// The CA's certificate in it.
    pub ca: PathBuf,
    /// The host's certificate.
    pub cert: PathBuf,
    /// The host's private key (`0600`).
    pub key: PathBuf,
    /// The names and addresses the certificate is valid for.
    pub names: Vec<String>,
    /// Valid until (UTC).
    pub not_after: String,
}

fn now() -> time::OffsetDateTime {
    time::OffsetDateTime::now_utc()
}

fn check_days(days: u32) -> Result<time::Duration, KeysError> {
    if (1..=36_500).contains(&days) {
        Ok(time::Duration::days(days as i64))
    } else {
        Err(KeysError::Days(days))
    }
}

fn make(what: impl Into<String>) -> impl FnOnce(rcgen::Error) -> KeysError {
    let what = what.into();
    move |source| KeysError::Make { what, source }
}

fn utc(t: time::OffsetDateTime) -> String {
    format!(
        "{:04}-{:02}-{:02} {:02}:{:02} UTC",
        t.year(),
        t.month() as u8,
        t.day(),
        t.hour(),
        t.minute()
    )
}

/// Write `text` to `dir/name` with mode `perm`; `new`: refuse an existing file.
fn write_file(
    dir: &Path,
    name: &str,
    text: &str,
    perm: u32,
    new: bool,
) -> Result<PathBuf, KeysError> {
    let path = dir.join(name);
    let mode = if new {
        FileMode::New
    } else {
        FileMode::Replace
    };
    let mut f = open_private_file(dir, name, mode, perm)?;
    // an existing file keeps its old mode: set it
    f.set_permissions(std::fs::Permissions::from_mode(perm))
        .and_then(|()| f.write_all(text.as_bytes()))
        .and_then(|()| f.sync_all())
        .map_err(|source| KeysError::Write {
            path: path.clone(),
            source,
        })?;
    Ok(path)
}

/// Make a flight CA in `dir` (created `0700` if missing), valid for `days`. Refuses a store
/// that holds one already: a new CA means issuing every host's certificate again.
pub fn init(dir: &Path, days: u32) -> Result<CaMade, KeysError> {
    let validity = check_days(days)?;
    let dir = ensure_private_dir(dir)?;
    for f in [CA_KEY_FILE, CA_CERT_FILE] {
        let path = dir.join(f);
        if std::fs::symlink_metadata(&path).is_ok() {
            return Err(KeysError::Exists {
                path,
                hint: "this store has a CA; keep it, or remove the store to start a new one (every host then needs a new certificate)",
            });
        }
    }
    let key = KeyPair::generate().map_err(make("generate the CA's key"))?;
    let mut params = CertificateParams::default();
    let mut dn = DistinguishedName::new();
    dn.push(DnType::OrganizationName, "AERIS-rs");
    dn.push(DnType::CommonName, "AERIS-rs flight CA");
    params.distinguished_name = dn;
    // a CA that signs host certificates only, never another CA
    params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    let start = now() - time::Duration::minutes(5);
    params.not_before = start;
    params.not_after = start + validity;
    let cert = params
        .self_signed(&key)
        .map_err(make("sign the flight CA"))?;
    let key_path = write_file(&dir, CA_KEY_FILE, &key.serialize_pem(), 0o600, true)?;
    let cert_path = write_file(&dir, CA_CERT_FILE, &cert.pem(), 0o644, true)?;
    Ok(CaMade {
        cert: cert_path,
        key: key_path,
        not_after: utc(params.not_after),
    })
}

/// Check `host` as a certificate and key-expression name.
pub fn check_host_name(host: &str) -> Result<(), KeysError> {
    if aeris_schemas::topics::is_valid_flight_name(host) {
        Ok(())
    } else {
        Err(KeysError::HostName(host.to_string()))
    }
}

/// The subject alternative names of `host`'s certificate: its name, the loopback names
/// (a host's own processes reach its agent there) and `addresses`.
fn alt_names(host: &str, addresses: &[String]) -> Result<(Vec<SanType>, Vec<String>), KeysError> {
    let mut sans = Vec::new();
    let mut names = Vec::new();
    let mut add = |s: &str| -> Result<(), KeysError> {
        if names.iter().any(|n| n == s) {
            return Ok(());
        }
        let san = match s.parse::<IpAddr>() {
            Ok(ip) => SanType::IpAddress(ip),
            Err(_) => {
                let dns_ok = !s.is_empty()
                    && s.len() <= 253
                    && s.split('.').all(|l| {
                        !l.is_empty()
                            && l.len() <= 63
                            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
                            && !l.starts_with('-')
                    });
                if !dns_ok {
                    return Err(KeysError::Address(s.to_string()));
                }
                SanType::DnsName(
                    s.try_into()
                        .map_err(|_| KeysError::Address(s.to_string()))?,
                )
            }
        };
        sans.push(san);
        names.push(s.to_string());
        Ok(())
    };
    add(host)?;
    for a in addresses {
        add(a)?;
    }
    for lo in ["localhost", "127.0.0.1", "::1"] {
        add(lo)?;
    }
    Ok((sans, names))
}

/// Issue host `host` an identity from the CA in `dir`: `dir/host/` with the CA's
/// certificate, the host's certificate (valid `days`, for `addresses` besides its name and
/// the loopback names) and its key. `replace`: rotate an existing identity (a new key).
pub fn issue(
    dir: &Path,
    host: &str,
    addresses: &[String],
    days: u32,
    replace: bool,
) -> Result<Issued, KeysError> {
    check_host_name(host)?;
    let validity = check_days(days)?;
    let (sans, names) = alt_names(host, addresses)?;
    let dir = ensure_private_dir(dir)?;
    let ca_cert_path = dir.join(CA_CERT_FILE);
    let ca_key_path = dir.join(CA_KEY_FILE);
    if !ca_cert_path.exists() || !ca_key_path.exists() {
        return Err(KeysError::NoCa { dir });
    }
    let read = |p: &Path| {
        std::fs::read_to_string(p).map_err(|e| KeysError::Ca {
            path: p.to_path_buf(),
            reason: e.to_string(),
        })
    };
    let ca_pem = read(&ca_cert_path)?;
    let ca_key = KeyPair::from_pem(&read(&ca_key_path)?).map_err(|e| KeysError::Ca {
        path: ca_key_path.clone(),
        reason: e.to_string(),
    })?;
    let issuer = Issuer::from_ca_cert_pem(&ca_pem, ca_key).map_err(|e| KeysError::Ca {
        path: ca_cert_path.clone(),
        reason: e.to_string(),
    })?;
    let out = crate::private_dir::private_subdir(&dir, host)?;
    let key_path = out.join(KEY_FILE);
    if !replace && std::fs::symlink_metadata(&key_path).is_ok() {
        return Err(KeysError::Exists {
            path: key_path,
            hint: "this host has an identity; `--replace` issues a new key and certificate (rotation)",
        });
    }
    let key = KeyPair::generate().map_err(make(format!("generate the key of host {host}")))?;
    let mut params = CertificateParams::default();
    let mut dn = DistinguishedName::new();
    dn.push(DnType::OrganizationName, "AERIS-rs");
    dn.push(DnType::CommonName, host);
    params.distinguished_name = dn;
    params.subject_alt_names = sans;
    params.is_ca = IsCa::ExplicitNoCa;
    params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
    params.extended_key_usages = vec![
        ExtendedKeyUsagePurpose::ServerAuth,
        ExtendedKeyUsagePurpose::ClientAuth,
    ];
    params.use_authority_key_identifier_extension = true;
    let start = now() - time::Duration::minutes(5);
    params.not_before = start;
    params.not_after = start + validity;
    let cert = params
        .signed_by(&key, &issuer)
        .map_err(make(format!("sign the certificate of host {host}")))?;
    // the key first: a certificate never stands beside another key than its own for long
    let key_path = write_file(&out, KEY_FILE, &key.serialize_pem(), 0o600, false)?;
    let cert_path = write_file(&out, CERT_FILE, &cert.pem(), 0o644, false)?;
    let ca_path = write_file(&out, CA_CERT_FILE, &ca_pem, 0o644, false)?;
    Ok(Issued {
        dir: out,
        ca: ca_path,
        cert: cert_path,
        key: key_path,
        names,
        not_after: utc(params.not_after),
    })
}

/// Why a host's identity cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum IdentityError {
    /// A file of the identity is missing.
    #[error(
        "{path} is missing: make the host's identity with `aeris keys issue STORE HOST` and copy STORE/HOST here"
    )]
    Missing {
        /// The file.
        path: PathBuf,
    },
    /// The private key can be read by others.
    #[error("{path} can be read by other users (mode {mode:o}): `chmod 600` it")]
    KeyExposed {
        /// The key file.
        path: PathBuf,
        /// Its mode.
        mode: u32,
    },
    /// A file is not a PEM certificate.
    #[error("{path} is not a PEM certificate: {reason}")]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The certificate was not signed by the CA beside it.
    #[error("{cert} was not signed by the CA in {ca}: issue it again from the flight's key store")]
    NotSignedByCa {
        /// The certificate.
        cert: PathBuf,
        /// The CA's certificate.
        ca: PathBuf,
    },
    /// The certificate has expired (or is not valid yet).
    #[error(
        "{path} is valid from {not_before} to {not_after}, not now: issue it again (`aeris keys issue STORE HOST --replace`)"
    )]
    Expired {
        /// The certificate.
        path: PathBuf,
        /// Valid from.
        not_before: String,
        /// Valid until.
        not_after: String,
    },
    /// The certificate has no common name.
    #[error("{path} names no host (no common name)")]
    NoName {
        /// The certificate.
        path: PathBuf,
    },
}

/// A host's identity, checked: its files, its name, until when it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// The identity directory.
    pub dir: PathBuf,
    /// The host's name (the certificate's common name).
    pub name: String,
    /// The CA's certificate.
    pub ca: PathBuf,
    /// The host's certificate.
    pub cert: PathBuf,
    /// The host's private key.
    pub key: PathBuf,
    /// Valid until (as X.509 says it).
    pub not_after: String,
    /// Seconds left until it expires.
    pub expires_in_s: i64,
}

fn read_pem_cert(path: &Path) -> Result<Vec<u8>, IdentityError> {
    let bytes = std::fs::read(path).map_err(|_| IdentityError::Missing {
        path: path.to_path_buf(),
    })?;
    let unreadable = |reason: String| IdentityError::Unreadable {
        path: path.to_path_buf(),
        reason,
    };
    let (_, pem) =
        x509_parser::pem::parse_x509_pem(&bytes).map_err(|e| unreadable(e.to_string()))?;
    if pem.label != "CERTIFICATE" {
        return Err(unreadable(format!(
            "a PEM `{}`, not a CERTIFICATE",
            pem.label
        )));
    }
    Ok(pem.contents)
}

impl Identity {
    /// Load and check the identity in `dir`: every file there, the key readable by its
    /// owner only, the certificate signed by the CA beside it and valid now.
    pub fn load(dir: &Path) -> Result<Identity, IdentityError> {
        let ca = dir.join(CA_CERT_FILE);
        let cert = dir.join(CERT_FILE);
        let key = dir.join(KEY_FILE);
        let key_meta =
            std::fs::metadata(&key).map_err(|_| IdentityError::Missing { path: key.clone() })?;
        let mode = key_meta.permissions().mode() & 0o777;
        if mode & 0o077 != 0 {
            return Err(IdentityError::KeyExposed { path: key, mode });
        }
        let ca_der = read_pem_cert(&ca)?;
        let cert_der = read_pem_cert(&cert)?;
        let (_, ca_x509) =
            X509Certificate::from_der(&ca_der).map_err(|e| IdentityError::Unreadable {
                path: ca.clone(),
                reason: e.to_string(),
            })?;
        let (_, x509) =
            X509Certificate::from_der(&cert_der).map_err(|e| IdentityError::Unreadable {
                path: cert.clone(),
                reason: e.to_string(),
            })?;
        if x509.verify_signature(Some(ca_x509.public_key())).is_err() {
            return Err(IdentityError::NotSignedByCa { cert, ca });
        }
        let validity = x509.validity();
        let not_after = validity.not_after.to_string();
        let Some(left) = validity.time_to_expiration() else {
            return Err(IdentityError::Expired {
                path: cert,
                not_before: validity.not_before.to_string(),
                not_after,
            });
        };
        let name = x509
            .subject()
            .iter_common_name()
            .next()
            .and_then(|cn| cn.as_str().ok())
            .map(str::to_string)
            .ok_or_else(|| IdentityError::NoName { path: cert.clone() })?;
        Ok(Identity {
            dir: dir.to_path_buf(),
            name,
            ca,
            cert,
            key,
            not_after,
            expires_in_s: left.whole_seconds(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_host_identity_issued_by_the_flight_ca_loads_with_its_name_and_private_key() {
        let t = tempfile::tempdir().unwrap();
        let store = t.path().join("keys");
        let ca = init(&store, 10).unwrap();
        assert_eq!(
            std::fs::metadata(&ca.key).unwrap().permissions().mode() & 0o777,
            0o600
        );
        let e = init(&store, 10).unwrap_err();
        assert!(matches!(e, KeysError::Exists { .. }), "{e}");
        let issued = issue(&store, "ground", &["10.0.0.2".into()], 2, false).unwrap();
        assert_eq!(
            issued.names,
            ["ground", "10.0.0.2", "localhost", "127.0.0.1", "::1"]
        );
        assert_eq!(
            std::fs::metadata(&issued.key).unwrap().permissions().mode() & 0o777,
            0o600
        );
        assert_eq!(
            std::fs::metadata(&issued.dir).unwrap().permissions().mode() & 0o777,
            0o700
        );
        let id = Identity::load(&issued.dir).unwrap();
        assert_eq!(id.name, "ground");
        assert!(
            id.expires_in_s > 86_000 && id.expires_in_s <= 2 * 86_400,
            "{id:?}"
        );
        // issuing again needs --replace; replacing gives a new key
        assert!(matches!(
            issue(&store, "ground", &[], 2, false),
            Err(KeysError::Exists { .. })
        ));
        let old = std::fs::read(&issued.key).unwrap();
        issue(&store, "ground", &[], 2, true).unwrap();
        assert_ne!(std::fs::read(&issued.key).unwrap(), old);
    }

    #[test]
    fn an_identity_of_another_ca_or_with_an_exposed_key_is_refused_by_file() {
        let t = tempfile::tempdir().unwrap();
        init(&t.path().join("a"), 10).unwrap();
        init(&t.path().join("b"), 10).unwrap();
        let ours = issue(&t.path().join("a"), "vehicle", &[], 1, false).unwrap();
        let theirs = issue(&t.path().join("b"), "vehicle", &[], 1, false).unwrap();
        // their certificate beside our CA
        std::fs::copy(&theirs.cert, &ours.cert).unwrap();
        let e = Identity::load(&ours.dir).unwrap_err();
        assert!(matches!(e, IdentityError::NotSignedByCa { .. }), "{e}");
        std::fs::set_permissions(&theirs.key, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = Identity::load(&theirs.dir).unwrap_err().to_string();
        assert!(
            e.contains("key.pem can be read by other users (mode 644)"),
            "{e}"
        );
        let e = Identity::load(&t.path().join("none"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("key.pem is missing"), "{e}");
    }

    #[test]
    fn bad_names_addresses_and_validities_are_refused_before_anything_is_written() {
        let t = tempfile::tempdir().unwrap();
        let store = t.path().join("keys");
        assert!(matches!(
            issue(&store, "ground", &[], 1, false),
            Err(KeysError::NoCa { .. })
        ));
        init(&store, 10).unwrap();
        for bad in ["../x", "Ground", "", "a/b"] {
            assert!(matches!(
                issue(&store, bad, &[], 1, false),
                Err(KeysError::HostName(_))
            ));
        }
        assert!(matches!(
            issue(&store, "g", &["bad name".into()], 1, false),
            Err(KeysError::Address(_))
        ));
        assert!(matches!(
            issue(&store, "g", &[], 0, false),
            Err(KeysError::Days(0))
        ));
        assert!(!store.join("g").exists());
    }
}
