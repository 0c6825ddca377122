//! Buffers reused from one matched pair to the next (S, cost and census volumes, selections):
//! fresh allocations of this size cost page faults on every pair.

/// Reused S and cost volumes: a video or a benchmark matches pair after pair of one size, and a
/// fresh 50–300 MB allocation per pair costs more in page faults than the matching itself.
pub(crate) static S_POOL: std::sync::Mutex<Vec<Vec<u16>>> = std::sync::Mutex::new(Vec::new());
/// Reused cost volumes (see [`S_POOL`]).
pub(crate) static C_POOL: std::sync::Mutex<Vec<Vec<u8>>> = std::sync::Mutex::new(Vec::new());

/// Reused selection buffers (see [`S_POOL`]; the second sweep writes every pixel).
pub(crate) static SEL_POOL: std::sync::Mutex<Vec<Vec<super::select::Selection>>> = std::sync::Mutex::new(Vec::new());

/// A buffer of `n` elements (contents unspecified: the users write every element before reading it).
pub(crate) fn take_buffer<T: Copy + Default>(pool: &std::sync::Mutex<Vec<Vec<T>>>, n: usize) -> Vec<T> {
    let mut v = pool.lock().map(|mut p| p.pop()).ok().flatten().unwrap_or_default();
    v.resize(n, T::default());
    v
}

/// Give a volume back for the next pair (at most three are kept).
pub(crate) fn recycle<T>(pool: &std::sync::Mutex<Vec<Vec<T>>>, v: Vec<T>) {
    if v.capacity() == 0 {
        return;
    }
    if let Ok(mut p) = pool.lock() {
        if p.len() < 3 {
            p.push(v);
        }
    }
}

/// Reused census images (see [`S_POOL`]).
pub(crate) static CENSUS_POOL: std::sync::Mutex<Vec<Vec<u64>>> = std::sync::Mutex::new(Vec::new());
