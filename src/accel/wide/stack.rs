//! The traversal stack of (child reference, entry distance).

use std::mem::MaybeUninit;

/// Traversal stack of (child reference, entry distance); never read beyond what was
/// pushed.
pub(super) struct Stack<const C: usize> {
    items: [MaybeUninit<Entry>; C],
    len: usize,
}

/// A stack entry, laid out for vector stores (`x86::sort_hits8`).
#[derive(Clone, Copy)]
#[repr(C)]
pub(super) struct Entry {
    pub(super) child: u32,
    pub(super) t: f32,
}

impl<const C: usize> Stack<C> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Stack { items: [const { MaybeUninit::uninit() }; C], len: 0 }
    }
    /// Empties the stack.
    #[inline(always)]
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }
    #[inline(always)]
    pub(super) fn push(&mut self, v: (u32, f32)) {
        // Bounds-checked: the build bounds the depth, so this never fails.
        self.items[self.len].write(Entry { child: v.0, t: v.1 });
        self.len += 1;
    }
    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<(u32, f32)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every index below `len` was written by `push` or `top8` before.
        let e = unsafe { self.items[self.len].assume_init() };
        Some((e.child, e.t))
    }
    /// The next 8 slots, for a vector store of which the caller then counts `n`
    /// (≤ 8) entries with `grow`.
    #[inline(always)]
    pub(super) fn top8(&mut self) -> &mut [MaybeUninit<Entry>; 8] {
        // Bounds-checked: the build bounds the depth (7 per level + 8), so this never fails.
        (&mut self.items[self.len..self.len + 8]).try_into().unwrap()
    }
    #[inline(always)]
    pub(super) fn grow(&mut self, n: usize) {
        debug_assert!(self.len + n <= C);
        self.len += n;
    }
}
