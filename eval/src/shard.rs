//! One of N disjoint shards of an evaluation's episodes (`aeris eval --shard K/N`).

/// Every `count`-th episode from the `index`-th (0-based): one of `count` disjoint shards
/// that together are the whole list (`--shard K/N` is index K-1 of N).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which shard, 0-based.
    pub index: usize,
    /// How many shards.
    pub count: usize,
}

/// Why `--shard` does not name a shard.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("not K/N with 1 <= K <= N (e.g. 1/4)")]
pub struct ShardError(pub String);

impl std::str::FromStr for Shard {
    type Err = ShardError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let err = || ShardError(text.to_string());
        let (k, n) = text.split_once('/').ok_or_else(err)?;
        let (k, n): (usize, usize) = (
            k.trim().parse().map_err(|_| err())?,
            n.trim().parse().map_err(|_| err())?,
        );
        if k == 0 || k > n {
            return Err(err());
        }
        Ok(Shard {
            index: k - 1,
            count: n,
        })
    }
}

impl Shard {
    /// Whether episode `k` (0-based, of the whole list) is this shard's.
    pub fn holds(&self, k: usize) -> bool {
        k % self.count == self.index
    }
}
