//! The stack every walk keeps its pending entries on (the binary walk, the wide single-ray and stream walks, the
//! coherent packets): a fixed array that is never initialized as a whole (for the wide walks, 14 KiB of memset a
//! ray cost more than a node visit), of which a walk only reads entries it wrote. Its capacity is the deepest a
//! verified file can make the walk; a push beyond it is dropped, which only a file that breaks the depth rules
//! (V30) can cause, and then the hits are unspecified but the walk stays safe.

use std::mem::MaybeUninit;

/// A stack of at most `N` entries of `T`; see the module's documentation.
pub(crate) struct WalkStack<T: Copy, const N: usize> {
    entries: [MaybeUninit<T>; N],
    /// Entries below this index are written.
    len: usize,
}

impl<T: Copy, const N: usize> WalkStack<T, N> {
    /// An empty stack, its array unwritten.
    pub(crate) const fn new() -> WalkStack<T, N> {
        WalkStack { entries: [const { MaybeUninit::uninit() }; N], len: 0 }
    }

    /// Empties the stack (for the next walk on it).
    #[inline(always)]
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// Pushes `entry`, or drops it when the stack is full.
    #[inline(always)]
    pub(crate) fn push(&mut self, entry: T) {
        if let Some(slot) = self.entries.get_mut(self.len) {
            slot.write(entry);
            self.len += 1;
        }
    }

    /// The entry pushed last and not yet popped, or `None` when there is none.
    #[inline(always)]
    #[allow(unsafe_code)] // reading an entry, see the SAFETY note
    pub(crate) fn pop(&mut self) -> Option<T> {
        self.len = self.len.checked_sub(1)?;
        // SAFETY: `push` writes entry `len` before it moves `len` past it, and nothing else raises `len`
        // (`clear` and this function only lower it), so every entry below `len` is written; the index read was
        // below `len` until this call lowered it by one.
        Some(unsafe { self.entries[self.len].assume_init() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pops_what_was_pushed_in_reverse_and_drops_pushes_beyond_capacity() {
        let mut stack = WalkStack::<(u32, f32), 3>::new();
        assert_eq!(stack.pop(), None);
        for k in 0..5 {
            stack.push((k, k as f32));
        }
        assert_eq!(stack.pop(), Some((2, 2.0)));
        stack.push((7, 7.0));
        assert_eq!(
            [stack.pop(), stack.pop(), stack.pop(), stack.pop()],
            [Some((7, 7.0)), Some((1, 1.0)), Some((0, 0.0)), None]
        );
        stack.push((9, 9.0));
        stack.clear();
        assert_eq!(stack.pop(), None);
    }
}
