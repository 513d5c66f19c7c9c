//! What the test suite skipped, and why, printed after it: cargo runs integration test targets in the order of
//! their names, so this one (`summary`) runs after `suite`, whose skips (`tests/suite/skips.rs`) are recorded in
//! a file of cargo's target temporary folder. A skip prints at once as well; this is the summary at the end,
//! where a run that left out real checks shows it. `BVHC_REQUIRE` turns a skip into a failure instead.

use std::collections::BTreeMap;
use std::io::Write;

#[test]
fn what_the_suite_skipped() {
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("skipped-checks.tsv");
    let text = std::fs::read_to_string(&path).unwrap_or_default();
    let records: Vec<[&str; 3]> = text
        .lines()
        .filter_map(|line| {
            let mut fields = line.splitn(3, '\t');
            Some([fields.next()?, fields.next()?, fields.next()?])
        })
        .collect();
    // The last suite run's records (a run that was not followed by this summary leaves older ones).
    let last_run = records.last().map(|r| r[0]);
    let mut by_need: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for record in records.iter().filter(|r| Some(r[0]) == last_run) {
        by_need.entry(record[1]).or_default().push(record[2]);
    }
    let mut summary = String::new();
    if by_need.is_empty() {
        summary += "test suite: no check was skipped\n";
    } else {
        let total: usize = by_need.values().map(Vec::len).sum();
        summary += &format!("test suite: {total} checks (or parts) skipped; BVHC_REQUIRE=<needs> makes them fail\n");
        for (need, whats) in &by_need {
            summary += &format!("  {need}: {} skipped, e.g. {}\n", whats.len(), whats[..whats.len().min(3)].join("; "));
        }
    }
    // Past the harness's capture, so a passing run shows it.
    let _ = std::io::stderr().write_all(summary.as_bytes());
    let _ = std::fs::remove_file(&path);
}
