//! [`ZeroOption`]: an optional value whose "none" is zero bytes.

/// An optional value that is all zero bytes when empty.
///
/// `Option<T>` stores `None` in a niche of `T` when `T` has one: the
/// invalid value `2` of a `bool` or one past the last variant of an enum
/// somewhere inside. A `const` blank estimator holding such an `Option` is
/// then not all zero bytes, and a `static` holding it is laid out in
/// `.data` (an image in flash, copied to RAM at start-up) instead of
/// `.bss`. The primitive representation keeps the tag a byte of its own,
/// 0 when empty, whatever `T` holds (checked by `tests/blank_bss.rs`).
/// For the fields of a blank value whose `T` has a niche; an `Option` of a
/// type without one (`Option<u64>`) already has its `None` at tag 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum ZeroOption<T> {
    /// Nothing (tag 0).
    None = 0,
    /// A value (tag 1).
    Some(T) = 1,
}

impl<T: Copy> ZeroOption<T> {
    /// The value as an `Option`.
    pub(crate) const fn get(&self) -> Option<T> {
        match self {
            Self::None => None,
            Self::Some(value) => Some(*value),
        }
    }
}

impl<T> ZeroOption<T> {
    /// A reference to the value, if any.
    pub(crate) const fn as_ref(&self) -> Option<&T> {
        match self {
            Self::None => None,
            Self::Some(value) => Some(value),
        }
    }
}

impl<T> From<Option<T>> for ZeroOption<T> {
    fn from(value: Option<T>) -> Self {
        match value {
            None => Self::None,
            Some(value) => Self::Some(value),
        }
    }
}
