//! Allocations that grow with the scene, made so that a refusal is an error rather than an abort.
//!
//! Rust aborts the process when an allocation fails; `try_reserve` reports it instead. The conversion asks for
//! its large arrays through these helpers where a stage can return the error (packing, writing, reading back),
//! and before the build and optimization stages, whose working sets are many small and medium vectors, it
//! **probes** for its estimated peak ([`probe`]): it reserves that many bytes and frees them at once, so a
//! process whose address space or memory cannot hold the stage stops with an error naming the stage before it
//! starts. The estimate is the budget's ([`crate::import::memory`]); a probe that passes does not promise that
//! every later allocation succeeds (other threads, fragmentation), but under an address-space limit, the case
//! where allocations fail rather than the kernel's out-of-memory killer acting, it turns the aborts measured
//! before into errors (`docs/scale.md`).

use bvhc_loader::Error;

fn refused(what: &str, bytes: usize) -> Error {
    Error::OutOfMemory { what: what.to_string(), bytes: bytes as u64 }
}

/// An empty vector with room for `n` elements of `T`, or [`Error::OutOfMemory`] naming `what`.
pub fn vec_with_capacity<T>(n: usize, what: &str) -> Result<Vec<T>, Error> {
    let mut vec = Vec::new();
    vec.try_reserve_exact(n).map_err(|_| refused(what, n.saturating_mul(size_of::<T>())))?;
    Ok(vec)
}

/// `n` copies of `value`, or [`Error::OutOfMemory`] naming `what`.
pub fn vec_of<T: Clone>(value: T, n: usize, what: &str) -> Result<Vec<T>, Error> {
    let mut vec = vec_with_capacity(n, what)?;
    vec.resize(n, value);
    Ok(vec)
}

/// `iter`'s items collected into a vector of exactly `n` (its length), or [`Error::OutOfMemory`].
pub fn collect_exact<T>(n: usize, iter: impl IntoIterator<Item = T>, what: &str) -> Result<Vec<T>, Error> {
    let mut vec = vec_with_capacity(n, what)?;
    vec.extend(iter);
    Ok(vec)
}

/// Whether `bytes` more can be allocated now: reserves them and frees them at once (the pages are never
/// touched, so this costs a system call, not the memory). [`Error::OutOfMemory`] naming `what` otherwise.
pub fn probe(bytes: usize, what: &str) -> Result<(), Error> {
    let mut headroom: Vec<u8> = Vec::new();
    headroom.try_reserve_exact(bytes).map_err(|_| refused(what, bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_are_errors_naming_what_and_how_much() {
        let error = vec_with_capacity::<u64>(usize::MAX / 4, "the test's array").unwrap_err();
        assert!(error.to_string().contains("the test's array"), "{error}");
        assert!(matches!(error, Error::OutOfMemory { bytes, .. } if bytes > 1 << 60));
        assert!(probe(usize::MAX / 2, "a huge stage").is_err());
        assert_eq!(vec_of(7u8, 3, "three").unwrap(), [7, 7, 7]);
        assert_eq!(collect_exact(3, 0..3, "three").unwrap(), [0, 1, 2]);
        probe(1 << 20, "a megabyte").unwrap();
    }
}
