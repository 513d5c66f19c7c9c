//! The choices and value parsers the options table's entries ([`super::table::OPTIONS`]) share.

use super::value::OptionValue;
use super::{OptimizeOver, Preset, Settings, SplitMethod, SplitTriangles};
use crate::builders::Builder;
use crate::import::{Instancing, Opacity};
use crate::optimize::Selection;

pub(super) const BUILDERS: [(&str, Builder); 2] =
    [("binned-sah", Builder::BinnedSah), ("spatial-median", Builder::SpatialMedian)];
pub(super) const INSTANCING: [(&str, Instancing); 3] =
    [("auto", Instancing::Auto), ("always", Instancing::Always), ("never", Instancing::Never)];
pub(super) const OPACITY: [(&str, Opacity); 3] =
    [("materials", Opacity::Materials), ("opaque", Opacity::Opaque), ("filtered", Opacity::Filtered)];
pub(super) const SPLIT_METHODS: [(&str, SplitMethod); 2] =
    [("sbvh", SplitMethod::Sbvh), ("pre-split", SplitMethod::PreSplit)];
pub(super) const SPLIT_TRIANGLES: [(&str, SplitTriangles); 3] =
    [("wasteful", SplitTriangles::Wasteful), ("any", SplitTriangles::Any), ("choose", SplitTriangles::Choose)];
pub(super) const OPTIMIZE_OVER: [(&str, OptimizeOver); 3] =
    [("references", OptimizeOver::References), ("clusters", OptimizeOver::Clusters), ("choose", OptimizeOver::Choose)];
pub(super) const SELECTIONS: [(&str, Selection); 5] = [
    ("comb", Selection::Comb),
    ("sum", Selection::Sum),
    ("min", Selection::Min),
    ("area", Selection::Area),
    ("random", Selection::Random),
];
pub(super) const PRESETS: [(&str, Preset); 3] =
    [("fast", Preset::Fast), ("balanced", Preset::Balanced), ("max-quality", Preset::MaxQuality)];

/// The names of a choice's values.
pub(super) const fn names<T, const N: usize>(choices: &[(&'static str, T); N]) -> [&'static str; N] {
    let mut names = [""; N];
    let mut i = 0;
    while i < N {
        names[i] = choices[i].0;
        i += 1;
    }
    names
}

/// The name `choices` gives `value`.
pub(super) fn name_of<T: PartialEq>(choices: &[(&'static str, T)], value: &T) -> String {
    choices.iter().find(|(_, v)| v == value).map_or("?", |(n, _)| n).to_string()
}

/// A switch's value: `true` sets it; for a `no_*` switch `false` asks for the opposite explicitly.
pub(super) fn on(value: &OptionValue) -> Result<bool, String> {
    value.boolean()
}

/// Sets one of the import limits that count (the others staying at their defaults, or as set).
pub(super) fn count_limit(
    settings: &mut Settings,
    value: &OptionValue,
    set: fn(&mut crate::import::ImportLimits, u64),
) -> Result<(), String> {
    let count = value.count()?;
    set(settings.overrides.limits.get_or_insert_with(Default::default), count);
    Ok(())
}

/// Stores a parsed value.
pub(super) fn put<T>(slot: &mut T, value: T) -> Result<(), String> {
    *slot = value;
    Ok(())
}

/// `--time-budget`: a finite, non-negative number of seconds, at most a year.
pub(super) fn seconds(value: &OptionValue) -> Result<std::time::Duration, String> {
    const MAX_SECONDS: f64 = 365.0 * 24.0 * 3600.0;
    let seconds = value.number()?;
    if !(0.0..=MAX_SECONDS).contains(&seconds) {
        return Err(format!("expected seconds from 0 to {MAX_SECONDS} (a year)"));
    }
    Ok(std::time::Duration::from_secs_f64(seconds))
}
