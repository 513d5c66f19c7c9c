//! The one macro that makes plain-data types (the on-disk types of `format` and `format_instances`, the aligned
//! blocks of `file`, the pages of `uncached`) castable from bytes.

/// Marks plain-data on-disk types as `bytemuck::Zeroable` and `bytemuck::Pod` (what the derive would do, without
/// its proc-macro dependencies), after proving at compile time that each has no padding: its size is the sum of
/// its fields' sizes.
macro_rules! plain_data {
    ($($ty:ty { $($field:ty),+ })+) => {$(
        const _: () = assert!(size_of::<$ty>() == 0 $(+ size_of::<$field>())+, "no padding");
        // SAFETY: `$ty` is `#[repr(C)]`, every field is an integer, a float or an array of them (all `Pod`: any
        // bit pattern is valid, all-zero included), and the assertion above proves there is no padding byte, so
        // every byte of a `$ty` is initialized and any bytes are a valid `$ty`. The type is `Copy` and `'static`.
        #[allow(unsafe_code)]
        unsafe impl bytemuck::Zeroable for $ty {}
        // SAFETY: as above.
        #[allow(unsafe_code)]
        unsafe impl bytemuck::Pod for $ty {}
    )+};
}
pub(crate) use plain_data;
