//! Sharding of dataset jobs (`--shard I/N`): N independent processes (Slurm array tasks,
//! Ray/Dask tasks) each take the items whose position `i` satisfies `i % N == I`, so that the
//! shards 0..N together cover every item exactly once and produce the files of one run.
use crate::error::{CoreError, Result};
use serde::{Deserialize, Serialize};

/// Shard `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: usize,
    /// Number of shards, ≥ 1.
    pub count: usize,
}

impl Shard {
    /// The whole job (shard 0 of 1).
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// A checked shard (`index < count`, `count ≥ 1`).
    pub fn new(index: usize, count: usize) -> Result<Shard> {
        if count == 0 || index >= count {
            return Err(CoreError::invalid("shard", format!("{index}/{count} (need 0 <= I < N)")));
        }
        Ok(Shard { index, count })
    }

    /// Whether item `i` belongs to this shard (`i % count == index`).
    pub fn contains(&self, i: usize) -> bool {
        i % self.count == self.index
    }

    /// The items of `items` that belong to this shard, in order.
    pub fn select<T>(&self, items: impl IntoIterator<Item = T>) -> Vec<T> {
        items.into_iter().enumerate().filter(|(i, _)| self.contains(*i)).map(|(_, x)| x).collect()
    }
}

impl std::str::FromStr for Shard {
    type Err = CoreError;
    /// `I/N`, e.g. `0/3`.
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || CoreError::invalid("shard", format!("'{s}' (expected I/N with 0 <= I < N, e.g. 0/3)"));
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i: usize = i.trim().parse().map_err(|_| bad())?;
        let n: usize = n.trim().parse().map_err(|_| bad())?;
        Shard::new(i, n).map_err(|_| bad())
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_items() {
        let n = 10;
        let mut seen = vec![0; n];
        for k in 0..3 {
            let s: Shard = format!("{k}/3").parse().unwrap();
            for i in s.select(0..n) {
                seen[i] += 1;
            }
        }
        assert_eq!(seen, vec![1; n]);
        assert_eq!(Shard::new(1, 3).unwrap().select(0..7), vec![1, 4]);
    }

    #[test]
    fn bad_shards_are_refused() {
        for s in ["3/3", "0/0", "1", "a/2", "-1/2", ""] {
            assert!(s.parse::<Shard>().is_err(), "{s}");
        }
        assert_eq!("2/5".parse::<Shard>().unwrap().to_string(), "2/5");
    }
}
