//! MAVLink 2 message signing on a link: the secret key (from a key file), the link id, and
//! the check every received frame passes when signing is on — unsigned frames (MAVLink 1
//! included) and frames whose signature or timestamp does not check are refused and
//! counted. The signature arithmetic (SHA-256 over key, frame and timestamp; per-stream
//! timestamps that must increase) is the `mavlink` crate's.

use mavlink::consts::v2::IFLAG_SIGNED;
use mavlink::{MAVLinkMessageRaw, MAVLinkV2MessageRaw, SigningConfig, SigningData};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The secret of a signed link and the link id this end signs with.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct LinkSigning {
    /// The 32-byte secret key.
    pub key: [u8; 32],
    /// The link id written into every signature.
    pub link_id: u8,
}

impl core::fmt::Debug for LinkSigning {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // never print the secret
        f.debug_struct("LinkSigning")
            .field("link_id", &self.link_id)
            .finish_non_exhaustive()
    }
}

/// Why a signing key file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum SigningKeyError {
    /// The file could not be read.
    #[error("cannot read the MAVLink signing key file `{path}`")]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file holds nothing.
    #[error("the MAVLink signing key file `{path}` is empty")]
    Empty {
        /// The file.
        path: PathBuf,
    },
}

impl LinkSigning {
    /// The key in `text`: 64 hexadecimal digits are the key itself; anything else is a
    /// passphrase whose SHA-256 is the key (as MAVProxy's `signing setup` and QGroundControl
    /// make it). Surrounding white space is ignored. `None` for an empty text.
    pub fn from_text(text: &str, link_id: u8) -> Option<Self> {
        let text = text.trim();
        if text.is_empty() {
            return None;
        }
        let mut key = [0u8; 32];
        let hex = text.len() == 64
            && text
                .as_bytes()
                .chunks(2)
                .zip(key.iter_mut())
                .all(|(pair, k)| {
                    core::str::from_utf8(pair)
                        .ok()
                        .and_then(|p| u8::from_str_radix(p, 16).ok())
                        .map(|b| *k = b)
                        .is_some()
                });
        if !hex {
            key.copy_from_slice(&Sha256::digest(text.as_bytes()));
        }
        Some(Self { key, link_id })
    }

    /// The key in the file at `path` (see [`LinkSigning::from_text`]).
    pub fn from_key_file(path: &Path, link_id: u8) -> Result<Self, SigningKeyError> {
        let text = std::fs::read_to_string(path).map_err(|source| SigningKeyError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_text(&text, link_id).ok_or_else(|| SigningKeyError::Empty {
            path: path.to_path_buf(),
        })
    }
}

/// What the signature check made of a received frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignatureVerdict {
    /// Signed with the key, timestamp fresh: accepted.
    Valid,
    /// Not signed (or MAVLink 1): refused.
    Unsigned,
    /// Signed, but the signature or the timestamp does not check: refused.
    Bad,
}

/// The signing state of one link: signs what it sends, checks what it receives, counts
/// the refusals.
pub(crate) struct LinkSigner {
    data: SigningData,
    unsigned_refused: AtomicU64,
    bad_refused: AtomicU64,
}

impl LinkSigner {
    pub(crate) fn new(signing: LinkSigning) -> Self {
        Self {
            data: SigningData::from_config(SigningConfig::new(
                signing.key,
                signing.link_id,
                true,
                false,
            )),
            unsigned_refused: AtomicU64::new(0),
            bad_refused: AtomicU64::new(0),
        }
    }

    /// Check `raw`, counting a refusal.
    pub(crate) fn check(&self, raw: &MAVLinkMessageRaw) -> SignatureVerdict {
        let verdict = match raw {
            MAVLinkMessageRaw::V1(_) => SignatureVerdict::Unsigned,
            MAVLinkMessageRaw::V2(v2) if v2.incompatibility_flags() & IFLAG_SIGNED == 0 => {
                SignatureVerdict::Unsigned
            }
            MAVLinkMessageRaw::V2(v2) if self.data.verify_signature(v2) => SignatureVerdict::Valid,
            MAVLinkMessageRaw::V2(_) => SignatureVerdict::Bad,
        };
        match verdict {
            SignatureVerdict::Valid => {}
            SignatureVerdict::Unsigned => {
                self.unsigned_refused.fetch_add(1, Ordering::Relaxed);
            }
            SignatureVerdict::Bad => {
                self.bad_refused.fetch_add(1, Ordering::Relaxed);
            }
        }
        verdict
    }

    /// Sign `raw` (serialised for signing).
    pub(crate) fn sign(&self, raw: &mut MAVLinkV2MessageRaw) {
        self.data.sign_message(raw);
    }

    /// `(unsigned, badly signed)` frames refused so far.
    pub(crate) fn refused(&self) -> (u64, u64) {
        (
            self.unsigned_refused.load(Ordering::Relaxed),
            self.bad_refused.load(Ordering::Relaxed),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_is_64_hex_digits_or_the_sha256_of_a_passphrase() {
        let hex = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
        let k = LinkSigning::from_text(&format!("  {hex}\n"), 3).unwrap();
        assert_eq!(k.key[..4], [0x00, 0x11, 0x22, 0x33]);
        assert_eq!(k.link_id, 3);
        // sha256("aeris") (from `printf aeris | sha256sum`)
        let p = LinkSigning::from_text("aeris\n", 0).unwrap();
        assert_eq!(p.key[..4], [0xd0, 0xf5, 0xfe, 0x6b], "{:02x?}", &p.key[..4]);
        assert!(LinkSigning::from_text(" \n", 0).is_none());
        assert!(
            !format!("{k:?}").contains("00112233"),
            "the key is never printed"
        );
    }
}
