//! A fixed-capacity ring of `Copy` values, newest first by age.
//!
//! Every buffer of the delay loop is one of these: no allocation, `O(1)` push,
//! `O(1)` random access by age (age 0 is the newest value).

/// Fixed-capacity ring buffer; pushing into a full ring drops the oldest value.
#[derive(Debug, Clone)]
pub(crate) struct Ring<E: Copy, const N: usize> {
    data: [E; N],
    /// Index where the next value is written.
    head: usize,
    len: usize,
}

impl<E: Copy, const N: usize> Ring<E, N> {
    /// An empty ring; `fill` only initializes the storage (a `const fn`:
    /// a ring in a `const` blank value costs no stack).
    pub(crate) const fn new(fill: E) -> Self {
        const { assert!(N > 0, "a ring needs room for at least one value") };
        Self {
            data: [fill; N],
            head: 0,
            len: 0,
        }
    }

    /// Appends a value, dropping the oldest one when full.
    #[inline]
    pub(crate) fn push(&mut self, value: E) {
        // `head < N` always; reduced here too so that the index is provably
        // in bounds (no reachable panic: benches/no-panic).
        let head = self.head % N;
        self.data[head] = value;
        self.head = (head + 1) % N;
        if self.len < N {
            self.len += 1;
        }
    }

    /// Number of stored values.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The value pushed `age` pushes ago (0 = newest), if still stored.
    #[inline]
    pub(crate) fn get(&self, age: usize) -> Option<E> {
        if age < self.len {
            Some(self.data[self.back(age + 1)])
        } else {
            None
        }
    }

    /// Removes and returns the oldest value.
    #[inline]
    pub(crate) fn pop_oldest(&mut self) -> Option<E> {
        if self.len == 0 {
            return None;
        }
        let oldest = self.data[self.back(self.len)];
        self.len -= 1;
        Some(oldest)
    }

    /// Replaces the newest value (nothing when empty).
    #[inline]
    pub(crate) fn replace_newest(&mut self, value: E) {
        if self.len > 0 {
            let newest = self.back(1);
            self.data[newest] = value;
        }
    }

    /// The oldest stored value.
    #[inline]
    pub(crate) fn oldest(&self) -> Option<E> {
        self.len.checked_sub(1).and_then(|age| self.get(age))
    }

    /// Index of the value written `steps` pushes before the next one
    /// (`1 <= steps <= len`). `head < N` and `steps <= N`, so `head + N - steps`
    /// neither overflows nor underflows: the wrapping operations only spare
    /// a debug build overflow checks that cannot fail (benches/no-panic).
    #[inline]
    fn back(&self, steps: usize) -> usize {
        self.head.wrapping_add(N).wrapping_sub(steps) % N
    }

    /// Forgets every value.
    #[inline]
    pub(crate) fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
    }
}
