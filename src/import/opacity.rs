//! Which triangles a conversion marks not opaque (`--opacity`), in the `triangle_flags` section of format 1.5
//! (`format-spec/bvh-1.md` 5.16): a tracer with a hit filter asks the filter about hits on those alone, so
//! opaque geometry pays nothing for alpha testing.

use bvhc_loader::format::TRIANGLE_NOT_OPAQUE;

use super::soup::TriangleSoup;

/// Which triangles are marked not opaque.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Opacity {
    /// Those whose material may cut them out: glTF primitives whose material's `alphaMode` is `MASK` or `BLEND`.
    /// OBJ and PLY inputs have none (their materials are not read). A scene with none gets no section.
    #[default]
    Materials,
    /// None: every triangle opaque, no section (filters never run on this file's hits).
    Opaque,
    /// Every triangle (filters run on every hit, whatever the materials say).
    Filtered,
}

impl Opacity {
    /// The name used in options.
    pub fn name(self) -> &'static str {
        match self {
            Opacity::Materials => "materials",
            Opacity::Opaque => "opaque",
            Opacity::Filtered => "filtered",
        }
    }

    /// The `triangle_flags` section for records whose source ids are `source_ids` (in record order), or `None`
    /// when no record is marked (the section is then left out, and the file is all opaque).
    pub fn record_flags(self, soup: &TriangleSoup, source_ids: &[u32]) -> Option<Vec<u8>> {
        let flag = |cut: bool| if cut { TRIANGLE_NOT_OPAQUE } else { 0 };
        match self {
            Opacity::Opaque => None,
            Opacity::Filtered => Some(vec![TRIANGLE_NOT_OPAQUE; source_ids.len()]),
            Opacity::Materials if !soup.cut_out.contains(&true) => None,
            Opacity::Materials => Some(source_ids.iter().map(|&id| flag(soup.is_cut_out(id))).collect()),
        }
    }
}
