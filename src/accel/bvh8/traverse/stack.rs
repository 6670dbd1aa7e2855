//! The traversal stack of [`super`]'s kernels.

use crate::accel::bvh8::STACK;
use std::mem::MaybeUninit;

/// The traversal stack: node or leaf entries with the distances at which
/// the ray enters their boxes. It is not cleared for every ray.
pub(super) struct Stack {
    pub(super) entry: Aligned<[MaybeUninit<u32>; STACK]>,
    pub(super) dist: Aligned<[MaybeUninit<f32>; STACK]>,
    pub(super) len: usize,
}

/// A stack array on a 32-byte boundary, as the 256-bit stores like.
#[repr(C, align(32))]
pub(super) struct Aligned<T>(pub(super) T);

impl Stack {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Stack {
            entry: Aligned([const { MaybeUninit::uninit() }; STACK]),
            dist: Aligned([const { MaybeUninit::uninit() }; STACK]),
            len: 0,
        }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, entry: u32, dist: f32) {
        // Indexing checks the bound; `STACK` covers the deepest tree.
        self.entry.0[self.len].write(entry);
        self.dist.0[self.len].write(dist);
        self.len += 1;
    }

    /// Pushes an entry without a distance, for [`Stack::pop_entry`] only.
    #[inline(always)]
    pub(super) fn push_entry(&mut self, entry: u32) {
        self.entry.0[self.len].write(entry);
        self.len += 1;
    }

    /// Pops an entry pushed with or without its distance.
    #[inline(always)]
    pub(super) fn pop_entry(&mut self) -> Option<u32> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: entries below `len` were written by a push or a visit.
        Some(unsafe { self.entry.0[self.len].assume_init() })
    }

    /// Pops an entry with its distance; only for stacks whose every entry
    /// was pushed with one.
    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<(u32, f32)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: items below `len` were written by `push` or a visit.
        unsafe {
            Some((
                self.entry.0[self.len].assume_init(),
                self.dist.0[self.len].assume_init(),
            ))
        }
    }
}
