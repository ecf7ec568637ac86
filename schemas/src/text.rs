//! Fixed-capacity UTF-8 text that can live in shared memory.

use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// UTF-8 text of at most `N` bytes, stored inline (no heap, no pointers).
///
/// Writing truncates at a character boundary, so the stored bytes are always valid UTF-8
/// when written through [`FixedText::set`]; [`FixedText::as_str`] still checks, because the
/// bytes may come from another process.
#[derive(Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
pub struct FixedText<const N: usize> {
    len: u32,
    bytes: [u8; N],
}

impl<const N: usize> FixedText<N> {
    /// Capacity in bytes.
    pub const CAPACITY: usize = N;

    /// Empty text.
    pub const fn new() -> Self {
        Self {
            len: 0,
            bytes: [0; N],
        }
    }

    /// Text holding `s`, truncated to the capacity at a character boundary.
    pub fn from_str_truncated(s: &str) -> Self {
        let mut t = Self::new();
        t.set(s);
        t
    }

    /// Replace the content with `s`, truncated at a character boundary; returns `true`
    /// when `s` was truncated. Never allocates.
    pub fn set(&mut self, s: &str) -> bool {
        let mut end = s.len().min(N);
        while end > 0 && !s.is_char_boundary(end) {
            end -= 1;
        }
        self.bytes[..end].copy_from_slice(&s.as_bytes()[..end]);
        self.bytes[end..].fill(0);
        self.len = end as u32;
        end < s.len()
    }

    /// Append `s` (truncating at the capacity); returns `true` when truncated.
    pub fn push_str(&mut self, s: &str) -> bool {
        let start = (self.len as usize).min(N);
        let room = N - start;
        let mut end = s.len().min(room);
        while end > 0 && !s.is_char_boundary(end) {
            end -= 1;
        }
        self.bytes[start..start + end].copy_from_slice(&s.as_bytes()[..end]);
        self.len = (start + end) as u32;
        end < s.len()
    }

    /// Stored length in bytes as claimed by the sender (may be corrupt).
    pub fn raw_len(&self) -> usize {
        self.len as usize
    }

    /// The text, or `None` when the length is out of range or the bytes are not UTF-8.
    pub fn as_str(&self) -> Option<&str> {
        let len = self.len as usize;
        if len > N {
            return None;
        }
        core::str::from_utf8(&self.bytes[..len]).ok()
    }

    /// The text, or `""` when it is corrupt (for display only).
    pub fn as_str_lossy(&self) -> &str {
        self.as_str().unwrap_or("")
    }

    /// `true` when the length is in range and the bytes are UTF-8.
    pub fn is_valid(&self) -> bool {
        self.as_str().is_some()
    }

    /// `true` when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl<const N: usize> Default for FixedText<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// `write!` into the text; a write that does not fit fails (what fits is kept).
impl<const N: usize> core::fmt::Write for FixedText<N> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        if self.push_str(s) {
            Err(core::fmt::Error)
        } else {
            Ok(())
        }
    }
}

impl<const N: usize> core::fmt::Debug for FixedText<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.as_str() {
            Some(s) => write!(f, "{s:?}"),
            None => write!(f, "<corrupt text len={}>", self.len),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncates_at_char_boundary() {
        let mut t = FixedText::<4>::new();
        assert!(t.set("aéé")); // a(1) é(2) é(2) = 5 bytes
        assert_eq!(t.as_str(), Some("aé"));
        assert!(!t.set("ab"));
        assert_eq!(t.as_str(), Some("ab"));
    }

    #[test]
    fn push_appends_until_full() {
        let mut t = FixedText::<5>::new();
        assert!(!t.push_str("ab"));
        assert!(t.push_str("cdef"));
        assert_eq!(t.as_str(), Some("abcde"));
    }

    #[test]
    fn corrupt_length_is_detected() {
        let mut t = FixedText::<4>::new();
        t.len = 9;
        assert_eq!(t.as_str(), None);
        assert!(!t.is_valid());
    }
}
