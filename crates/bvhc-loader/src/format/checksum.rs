//! The checksums of `format-spec/bvh-1.md`: XXH3-64 with seed 0, stored as a little-endian `u64`.

use xxhash_rust::xxh3::{Xxh3, xxh3_64};

/// Byte offset of `FileHeader::header_checksum` within the header.
pub const HEADER_CHECKSUM_BYTE_OFFSET: usize = 32;

/// XXH3-64 of the header and section table (`header_and_table`), with the 8 bytes of `header_checksum` counted
/// as zero.
pub fn header_checksum(header_and_table: &[u8]) -> u64 {
    let split = HEADER_CHECKSUM_BYTE_OFFSET.min(header_and_table.len());
    let rest = (HEADER_CHECKSUM_BYTE_OFFSET + 8).min(header_and_table.len());
    let mut hasher = Xxh3::new();
    hasher.update(&header_and_table[..split]);
    hasher.update(&[0u8; 8][..rest - split]);
    hasher.update(&header_and_table[rest..]);
    hasher.digest()
}

/// XXH3-64 of a section's bytes.
pub fn section_checksum(section: &[u8]) -> u64 {
    xxh3_64(section)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_checksum_ignores_its_own_field() {
        let mut bytes = [7u8; 112];
        let before = header_checksum(&bytes);
        bytes[HEADER_CHECKSUM_BYTE_OFFSET..HEADER_CHECKSUM_BYTE_OFFSET + 8].fill(0xAB);
        assert_eq!(header_checksum(&bytes), before);
        bytes[0] = 8;
        assert_ne!(header_checksum(&bytes), before);
    }

    #[test]
    fn streaming_equals_one_shot_over_zeroed_field() {
        let mut bytes: Vec<u8> = (0..200u32).map(|i| (i * 31) as u8).collect();
        bytes[HEADER_CHECKSUM_BYTE_OFFSET..HEADER_CHECKSUM_BYTE_OFFSET + 8].fill(0);
        assert_eq!(header_checksum(&bytes), xxh3_64(&bytes));
    }

    #[test]
    fn known_value_of_empty_input() {
        // XXH3_64bits("") with seed 0, from the xxHash reference.
        assert_eq!(section_checksum(&[]), 0x2D06_8005_38D3_94C2);
    }
}
