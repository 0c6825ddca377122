//! The extension's global allocator: the system allocator plus a small cache of freed large
//! blocks (≥ 1 MiB), reused for the next allocation of exactly the same size and alignment.
//!
//! Why: a binding call on a 1280×1024 stereo sample allocates ~35 MB of images and masks (copies
//! of the inputs, the outputs handed to NumPy). glibc returns such blocks to the kernel when
//! they are freed, so every call paid page faults and page zeroing again (≈ 30 % of a CATS call
//! with the thesis rule in `perf`). Repeated calls on same-sized data now reuse warm pages.
//!
//! Correctness: every block, cached or not, was allocated by [`System`] with the layout it is
//! handed out for (exact size and alignment match), so `System.dealloc` / `System.realloc` stay
//! valid for it. The cache is guarded by a try-lock: when it is busy (or was held by another
//! thread across a `fork`), calls go straight to the system allocator, so nothing ever blocks.
//! The cache holds at most [`set_buffer_cache_mb`] MiB (default 256; 0 disables it) in at most
//! 32 blocks, oldest evicted first.
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Smallest block kept in the cache (bytes).
const MIN_CACHED: usize = 1 << 20;
/// Most blocks kept.
const MAX_BLOCKS: usize = 32;
/// Largest total size kept (bytes); 0 = no cache.
static MAX_BYTES: AtomicUsize = AtomicUsize::new(256 << 20);

struct Blocks {
    /// (address, size, align), oldest first.
    list: [(usize, usize, usize); MAX_BLOCKS],
    n: usize,
    bytes: usize,
}

/// System allocator + large-block cache (see the module documentation).
pub struct CachingAlloc {
    lock: AtomicBool,
    blocks: UnsafeCell<Blocks>,
}

// SAFETY: `blocks` is only accessed while `lock` is held (acquire/release).
unsafe impl Sync for CachingAlloc {}

impl CachingAlloc {
    /// An empty cache.
    pub const fn new() -> Self {
        CachingAlloc {
            lock: AtomicBool::new(false),
            blocks: UnsafeCell::new(Blocks { list: [(0, 0, 0); MAX_BLOCKS], n: 0, bytes: 0 }),
        }
    }

    /// Run `f` on the cache if it is free now; `None` when another thread holds it.
    fn with<R>(&self, f: impl FnOnce(&mut Blocks) -> R) -> Option<R> {
        if self.lock.compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed).is_err() {
            return None;
        }
        // SAFETY: the lock is held, so this is the only reference.
        let r = f(unsafe { &mut *self.blocks.get() });
        self.lock.store(false, Ordering::Release);
        Some(r)
    }

    /// A cached block of exactly this layout, removed from the cache.
    fn take(&self, layout: Layout) -> Option<*mut u8> {
        if layout.size() < MIN_CACHED {
            return None;
        }
        self.with(|b| {
            let i = (0..b.n).rev().find(|&i| b.list[i].1 == layout.size() && b.list[i].2 == layout.align())?;
            let p = b.list[i].0 as *mut u8;
            b.list.copy_within(i + 1..b.n, i);
            b.n -= 1;
            b.bytes -= layout.size();
            Some(p)
        })
        .flatten()
    }
}

impl Default for CachingAlloc {
    fn default() -> Self {
        Self::new()
    }
}

unsafe impl GlobalAlloc for CachingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        match self.take(layout) {
            Some(p) => p,
            // SAFETY: forwarded with the caller's (valid, non-zero-size) layout.
            None => unsafe { System.alloc(layout) },
        }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        match self.take(layout) {
            Some(p) => {
                // SAFETY: `p` is a live block of `layout.size()` bytes.
                unsafe { std::ptr::write_bytes(p, 0, layout.size()) };
                p
            }
            // SAFETY: forwarded with the caller's layout.
            None => unsafe { System.alloc_zeroed(layout) },
        }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        let cap = MAX_BYTES.load(Ordering::Relaxed);
        if layout.size() >= MIN_CACHED && layout.size() <= cap {
            let kept = self.with(|b| {
                while b.n > 0 && (b.n == MAX_BLOCKS || b.bytes + layout.size() > cap) {
                    let (p, s, a) = b.list[0];
                    b.list.copy_within(1..b.n, 0);
                    b.n -= 1;
                    b.bytes -= s;
                    // SAFETY: cached blocks were allocated by System with exactly (s, a).
                    unsafe { System.dealloc(p as *mut u8, Layout::from_size_align_unchecked(s, a)) };
                }
                b.list[b.n] = (ptr as usize, layout.size(), layout.align());
                b.n += 1;
                b.bytes += layout.size();
            });
            if kept.is_some() {
                return;
            }
        }
        // SAFETY: `ptr` was allocated by System with `layout` (cached or not).
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: every block is a System allocation of `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Largest total size (MiB) of freed large buffers the extension keeps for reuse (default 256;
/// 0 frees every buffer at once). Cached buffers are released as the limit is lowered.
#[pyo3::pyfunction]
pub fn set_buffer_cache_mb(mb: usize) {
    let cap = mb.saturating_mul(1 << 20);
    MAX_BYTES.store(cap, Ordering::Relaxed);
    crate::ALLOC.with(|b| {
        while b.n > 0 && b.bytes > cap {
            let (p, s, a) = b.list[0];
            b.list.copy_within(1..b.n, 0);
            b.n -= 1;
            b.bytes -= s;
            // SAFETY: cached blocks were allocated by System with exactly (s, a).
            unsafe { System.dealloc(p as *mut u8, Layout::from_size_align_unchecked(s, a)) };
        }
    });
}
