//! The traversal stack of (child reference, entry distance).

use std::mem::MaybeUninit;

/// Traversal stack of (child reference, entry distance) in the storage `S` (an
/// array of entries, or a borrow of one); never read beyond what was pushed.
///
/// A traversal keeps its array in a separate local and borrows it here, so that the
/// length is a plain local of its own that LLVM keeps in a register; as a field next
/// to the array it stayed in memory, loaded and stored at every push and pop.
pub(super) struct Stack<S> {
    items: S,
    len: usize,
}

/// Storage for the entries of a [`Stack`] of capacity C.
pub(super) type Items<const C: usize> = [MaybeUninit<Entry>; C];

/// Empty storage for a stack of capacity C.
#[inline(always)]
pub(super) const fn items<const C: usize>() -> Items<C> {
    [const { MaybeUninit::uninit() }; C]
}

/// A stack entry, laid out for vector stores (`x86::sort_hits8`).
#[derive(Clone, Copy)]
#[repr(C)]
pub(super) struct Entry {
    pub(super) child: u32,
    pub(super) t: f32,
}

impl<S: AsMut<[MaybeUninit<Entry>]>> Stack<S> {
    #[inline(always)]
    pub(super) fn new(items: S) -> Self {
        Stack { items, len: 0 }
    }
    /// Empties the stack.
    #[inline(always)]
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }
    #[inline(always)]
    pub(super) fn push(&mut self, v: (u32, f32)) {
        // Bounds-checked: the build bounds the depth, so this never fails.
        self.items.as_mut()[self.len].write(Entry { child: v.0, t: v.1 });
        self.len += 1;
    }
    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<(u32, f32)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every index below `len` was written by `push` or `top8` before.
        let e = unsafe { self.items.as_mut()[self.len].assume_init() };
        Some((e.child, e.t))
    }
    /// The next 8 slots, for a vector store of which the caller then counts `n`
    /// (≤ 8) entries with `grow`.
    #[inline(always)]
    pub(super) fn top8(&mut self) -> &mut [MaybeUninit<Entry>; 8] {
        // Bounds-checked: the build bounds the depth (7 per level + 8), so this never fails.
        (&mut self.items.as_mut()[self.len..self.len + 8]).try_into().unwrap()
    }
    #[inline(always)]
    pub(super) fn grow(&mut self, n: usize) {
        debug_assert!(self.len + n <= self.items.as_mut().len());
        self.len += n;
    }
}
