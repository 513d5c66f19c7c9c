//! Rules V52 and V53 (since 1.5): the `triangle_flags` section sets only the bits its minor version defines, and
//! the records of one source triangle (the records of one id: a triangle's split references) have the same
//! flags, so a hit on any of them is filtered alike.

use std::collections::HashMap;

use crate::error::{Rule, Violation, violation};
use crate::format::TRIANGLE_FLAGS_DEFINED;

/// V52 (when the file's minor version is one this reader knows: a higher minor may define more bits) and V53.
pub(crate) fn verify_triangle_flags(
    flags: &[u8],
    triangle_ids: Option<&[u32]>,
    known_minor: bool,
) -> Result<(), Violation> {
    if known_minor && let Some(i) = flags.iter().position(|&f| f & !TRIANGLE_FLAGS_DEFINED != 0) {
        return Err(violation(
            Rule::TriangleFlagBits,
            format!(
                "triangle {i}: flags {:#04x} set bits this version does not define (only {TRIANGLE_FLAGS_DEFINED:#04x})",
                flags[i]
            ),
        ));
    }
    let Some(ids) = triangle_ids else { return Ok(()) };
    let mut first_of_id: HashMap<u32, (usize, u8)> = HashMap::new();
    for (i, (&id, &f)) in ids.iter().zip(flags).enumerate() {
        match first_of_id.get(&id) {
            Some(&(first, first_flags)) if first_flags != f => {
                return Err(violation(
                    Rule::TriangleFlagsAgree,
                    format!(
                        "triangle {i}: flags {f:#04x}, but triangle {first} of the same id {id} has {first_flags:#04x}"
                    ),
                ));
            }
            Some(_) => {}
            None => {
                first_of_id.insert(id, (i, f));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undefined_bits_and_references_that_disagree_are_refused() {
        assert!(verify_triangle_flags(&[0, 1, 1, 0], Some(&[4, 5, 5, 6]), true).is_ok());
        let bits = verify_triangle_flags(&[0, 3], None, true).unwrap_err();
        assert_eq!((bits.rule, bits.detail.contains("triangle 1")), (Rule::TriangleFlagBits, true));
        assert!(verify_triangle_flags(&[0, 0x80], None, false).is_ok(), "a higher minor may define the bit");
        let agree = verify_triangle_flags(&[1, 0, 0], Some(&[9, 8, 9]), true).unwrap_err();
        assert_eq!(agree.rule, Rule::TriangleFlagsAgree);
        assert!(agree.detail.contains("triangle 2") && agree.detail.contains("same id 9"), "{agree}");
    }
}
