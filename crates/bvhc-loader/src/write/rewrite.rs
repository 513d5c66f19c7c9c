//! A file written anew after an edit ([`BvhFile::edit`] changes boxes and vertices in place, so the costs the
//! metadata states go stale): [`BvhFile::rewritten`] recomputes them, lays the file out again around the
//! metadata's new length, and verifies the result; [`BvhView::rewritten_recording`] also records, in a top-level
//! metadata member, where the edit came from (`bvhc refit --positions` records its asset as `refit`).

use crate::error::{Error, violation};
use crate::open::file::BvhFile;
use crate::open::view::BvhView;
use crate::verify::costs::{FileCosts, stated_costs};
use crate::verify::json::parse_object;
use crate::write::writer::BvhWriter;

impl BvhFile {
    /// This file laid out anew with the costs its metadata states recomputed from its sections: `cost.sah_cost`,
    /// `cost.inner_area_ratio` and `cost.leaf_area_ratio` (section 5.6) and `wide.cost` (section 6.1), each where
    /// the metadata has it (rule V37 says which). A cost whose stated number is already the recomputed f64 keeps
    /// its text; another is written as the shortest text that reads back as the recomputed f64. Once a cost
    /// changes, the metadata's `choice` goes too: its candidates' costs were measured on the geometry converted,
    /// not on this one, and rule V39 ties the kept one to the file's cost. Every other byte of the metadata and
    /// every other section is kept; the checksums are computed, and the result is verified fully (as
    /// [`BvhWriter::build`] does), so it is a valid file or an error.
    ///
    /// For a file the converter wrote and nobody edited, the same bytes. This is what makes an edited file
    /// (after [`BvhFile::edit`]) pass `verify` again, and what a program writes out
    /// ([`crate::write::write_atomic`]) to ship it.
    pub fn rewritten(&self) -> Result<BvhFile, Error> {
        self.view().rewritten()
    }

    /// [`BvhView::rewritten_recording`] of this file.
    pub fn rewritten_recording(&self, name: &str, value: Option<&str>) -> Result<BvhFile, Error> {
        self.view().rewritten_recording(name, value)
    }
}

impl BvhView<'_> {
    /// [`BvhFile::rewritten`] of the bytes this view reads (a refit binding's own array, a map), without first
    /// copying them into a `BvhFile`.
    pub fn rewritten(&self) -> Result<BvhFile, Error> {
        let metadata = match self.metadata_str() {
            Some(text) => Some(metadata_with_costs(self, text?)?),
            None => None,
        };
        let mut writer = BvhWriter::from_view(self);
        if let Some(metadata) = &metadata {
            writer = writer.metadata(metadata);
        }
        writer.build()
    }

    /// [`BvhView::rewritten`] with the top-level metadata member `name` set to `value` (JSON text), or with
    /// `None` removed: every member of that name the metadata had is removed and the new one goes last, so a
    /// file edited twice records the last edit; a file without metadata gets `{name: value}` (and stays without
    /// for `None`). bvhc records a refit to an asset's pose as `refit` (`format-spec/bvh-1.md` 5.5). Refused: a
    /// `value` that is not one JSON value, a name that JSON cannot hold as written (a quote, a backslash or a
    /// control character in it).
    pub fn rewritten_recording(&self, name: &str, value: Option<&str>) -> Result<BvhFile, Error> {
        let unwritable = |why: String| Error::Unwritable(format!("metadata member {name:?}: {why}"));
        if name.chars().any(|c| c == '"' || c == '\\' || c.is_control()) {
            return Err(unwritable("a name JSON cannot hold without escapes".into()));
        }
        let member = value.map(|value| format!("\"{name}\":{}", value.trim()));
        if let Some(member) = &member {
            parse_object(&format!("{{{member}}}")).map_err(|e| unwritable(format!("not one JSON value: {e}")))?;
        }
        let text = match (self.metadata_str(), &member) {
            (Some(text), _) => metadata_with_costs(self, text?)?,
            (None, Some(_)) => "{}".to_string(),
            (None, None) => return self.rewritten(),
        };
        let metadata = with_member(&text, name, member.as_deref())?;
        BvhWriter::from_view(self).metadata(&metadata).build()
    }
}

/// `text` (a JSON object) without its members named `name` and with `member` (`"name":value`), if any, last.
fn with_member(text: &str, name: &str, member: Option<&str>) -> Result<String, Error> {
    let unreadable = |e: String| violation(crate::error::Rule::Metadata, format!("metadata section: {e}"));
    let mut edited = text.to_string();
    while let Some(span) = parse_object(&edited).map_err(unreadable)?.removal_span(name) {
        edited.replace_range(span, "");
    }
    let Some(member) = member else { return Ok(edited) };
    match parse_object(&edited).map_err(unreadable)?.end_of_members() {
        Some(end) => edited.insert_str(end, &format!(",{member}")),
        None => {
            // An empty object: the member goes after its brace (parse_object found one first).
            let brace = edited.find('{').map_or(0, |at| at + 1);
            edited.insert_str(brace, member);
        }
    }
    Ok(edited)
}

/// `text`, the metadata of `view`, with its stated costs replaced by the file's and, when one changed, its
/// `choice` member removed.
fn metadata_with_costs(view: &BvhView<'_>, text: &str) -> Result<String, Error> {
    let unreadable = |e: String| violation(crate::error::Rule::Metadata, format!("metadata section: {e}"));
    let metadata = parse_object(text).map_err(unreadable)?;
    let mut replacements = Vec::new();
    for cost in stated_costs(view, &metadata, &FileCosts(view)) {
        if cost.stated.value().to_bits() == cost.computed.to_bits() {
            continue;
        }
        if !cost.computed.is_finite() {
            return Err(Error::Unwritable(format!(
                "metadata {}: the recomputed cost {} is not a number JSON can hold",
                cost.name, cost.computed
            )));
        }
        // `{:?}` writes the shortest digits that read back as the same f64, with an exponent only for very
        // large or small values: always a JSON number.
        replacements.push((cost.stated.span(), format!("{:?}", cost.computed)));
    }
    if replacements.is_empty() {
        return Ok(text.to_string());
    }
    let mut rewritten = text.to_string();
    replacements.sort_by_key(|(span, _)| std::cmp::Reverse(span.start));
    for (span, number) in replacements {
        rewritten.replace_range(span, &number);
    }
    // Every `choice` member (a repeated name's last counts, so an earlier one would count once the last went).
    while let Some(span) = parse_object(&rewritten).map_err(unreadable)?.removal_span("choice") {
        rewritten.replace_range(span, "");
    }
    Ok(rewritten)
}
