//! Rule V37 of `format-spec/bvh-1.md`: the costs the metadata states are the file's. One list
//! ([`stated_costs`]) says which metadata numbers are costs and what the file's sections make them, so that the
//! verifier compares them and a writer that rewrites them after an edit (`BvhFile::rewritten`) replaces the
//! same numbers.

use crate::error::{Rule, Violation, violation};
use crate::format::cost::{BinaryCost, binary_cost, wide_cost};
use crate::open::view::BvhView;
use crate::verify::json::{Map, Number, Value};

/// Largest relative difference accepted between a cost in the metadata and the cost recomputed from the file
/// (V37): summing in another order than the spec's changes the last bits, never the ninth digit.
pub const COST_TOLERANCE: f64 = 1e-9;

/// One cost the metadata states, and the value the file's sections give it.
pub(crate) struct StatedCost<'m> {
    /// The member's path in the metadata, e.g. `cost.sah_cost`.
    pub name: &'static str,
    /// The number as the metadata writes it (and where).
    pub stated: &'m Number,
    /// The cost recomputed from the file (sections 5.6 and 6.1).
    pub computed: f64,
    /// What it is the cost of, for messages: `tree` or `wide tree`.
    pub of: &'static str,
}

/// Whether `stated` is `computed` within [`COST_TOLERANCE`] relative to `computed`.
pub(crate) fn close(stated: f64, computed: f64) -> bool {
    (stated - computed).abs() <= COST_TOLERANCE * computed.abs()
}

/// Every cost `metadata` states that this version defines for `view`: `cost.sah_cost`,
/// `cost.inner_area_ratio` and `cost.leaf_area_ratio` (section 5.6, under `cost.c_t` and `cost.c_i`, 3 and 2
/// when absent), and `wide.cost` (section 6.1, under `build.wide`'s `node_visit` and `packet_test`, 1 when
/// absent) where the file has wide sections and the metadata `build.wide`. None for a two-level file (1.3
/// defines no cost for one), and none for a member whose value is not a number. `computed` gives the costs the
/// file's sections make them: [`FileCosts`] sums them in the spec's order, a refit from the sums it kept.
pub(crate) fn stated_costs<'m>(view: &BvhView<'_>, metadata: &'m Map, computed: &impl CostsOf) -> Vec<StatedCost<'m>> {
    let mut stated = Vec::new();
    if view.two_level().is_some() {
        return stated;
    }
    let number_of = |record: &'m Map, key: &str| record.get(key).and_then(Value::as_number);
    if let Some(record) = metadata.object("cost") {
        let (c_t, c_i) = (record.number("c_t").unwrap_or(3.0), record.number("c_i").unwrap_or(2.0));
        let cost = computed.binary(c_t, c_i);
        for (name, key, computed) in [
            ("cost.sah_cost", "sah_cost", cost.sah_cost),
            ("cost.inner_area_ratio", "inner_area_ratio", cost.inner_area_ratio),
            ("cost.leaf_area_ratio", "leaf_area_ratio", cost.leaf_area_ratio),
        ] {
            if let Some(number) = number_of(record, key) {
                stated.push(StatedCost { name, stated: number, computed, of: "tree" });
            }
        }
    }
    let number = metadata.object("wide").and_then(|wide| number_of(wide, "cost"));
    let constants = metadata.object("build").and_then(|build| build.object("wide"));
    if let (Some(number), Some(constants), Some(_)) = (number, constants, view.wide_sections()) {
        let node_visit = constants.number("node_visit").unwrap_or(1.0);
        let packet_test = constants.number("packet_test").unwrap_or(1.0);
        let computed = computed.wide(node_visit, packet_test);
        stated.push(StatedCost { name: "wide.cost", stated: number, computed, of: "wide tree" });
    }
    stated
}

/// The costs of a file's trees under given constants (sections 5.6 and 6.1).
pub(crate) trait CostsOf {
    /// The binary tree's cost under `c_t` and `c_i`.
    fn binary(&self, c_t: f64, c_i: f64) -> BinaryCost;
    /// The wide tree's cost under `node_visit` and `packet_test` (called only for a file with wide sections).
    fn wide(&self, node_visit: f64, packet_test: f64) -> f64;
}

/// The costs of a view's trees summed as the spec states them ([`binary_cost`], [`wide_cost`]), bit for bit.
pub(crate) struct FileCosts<'v, 'a>(pub &'v BvhView<'a>);

impl CostsOf for FileCosts<'_, '_> {
    fn binary(&self, c_t: f64, c_i: f64) -> BinaryCost {
        binary_cost(self.0.nodes(), c_t, c_i)
    }

    fn wide(&self, node_visit: f64, packet_test: f64) -> f64 {
        let nodes = self.0.wide_sections().map_or(&[][..], |sections| sections.nodes);
        wide_cost(self.0.nodes().first(), nodes, node_visit, packet_test)
    }
}

/// V37: `cost` and `wide.cost` equal the costs recomputed from the file; a two-level file states neither.
pub(crate) fn verify_costs(view: &BvhView<'_>, metadata: &Map) -> Result<(), Violation> {
    let wide_cost_stated = metadata.object("wide").is_some_and(|wide| wide.get("cost").is_some());
    if view.two_level().is_some() && (metadata.get("cost").is_some() || wide_cost_stated) {
        return Err(violation(
            Rule::MetadataCost,
            "metadata cost or wide.cost in a two-level file, for which 1.3 defines no cost".to_string(),
        ));
    }
    match stated_costs(view, metadata, &FileCosts(view))
        .into_iter()
        .find(|cost| !close(cost.stated.value(), cost.computed))
    {
        Some(cost) => Err(violation(
            Rule::MetadataCost,
            format!("metadata {} {}, but the {}'s is {}", cost.name, cost.stated.value(), cost.of, cost.computed),
        )),
        None => Ok(()),
    }
}
