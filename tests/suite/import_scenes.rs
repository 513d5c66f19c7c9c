//! Every scene of the shared folder imports with the counts its README gives.

use std::path::Path;

use bvhc::import::{ImportOptions, ImportReport, Instancing, import};

use crate::common::scenes_dir;

/// One row of the scenes README's table.
#[derive(Debug)]
struct Expected {
    file: String,
    triangles: u64,
    instanced: u64,
    repeated_index: u64,
    zero_area: u64,
    unreferenced_vertices: Option<u64>,
    draco: bool,
}

fn number_after(notes: &str, label: &str) -> Option<u64> {
    let start = notes.find(label)? + label.len();
    notes[start..].trim_start().split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

fn expected_rows(readme: &str) -> Vec<Expected> {
    readme
        .lines()
        .filter(|line| line.starts_with("| ") && line.contains('/') && !line.starts_with("| file"))
        .filter_map(|line| {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            let (file, count, notes) = (cells.get(1)?, cells.get(3)?, cells.get(4).copied().unwrap_or(""));
            let triangles: u64 = count.split_whitespace().next()?.parse().ok()?;
            let instanced = number_after(count, "(instanced").unwrap_or(triangles);
            Some(Expected {
                file: file.to_string(),
                triangles,
                instanced,
                repeated_index: number_after(notes, "degenerate dup index:").unwrap_or(0),
                zero_area: number_after(notes, "degenerate zero area:").unwrap_or(0),
                unreferenced_vertices: number_after(notes, "unreferenced vertices:"),
                draco: notes.contains("KHR_draco_mesh_compression"),
            })
        })
        .collect()
}

fn check(expected: &Expected, report: &ImportReport) -> Vec<String> {
    let mut wrong = Vec::new();
    let mut compare = |what: &str, got: u64, want: u64| {
        if got != want {
            wrong.push(format!("{what}: got {got}, README {want}"));
        }
    };
    compare("triangles in the file's meshes", report.file_mesh_triangles, expected.triangles);
    compare("instanced triangles", report.source_triangles, expected.instanced);
    compare("unique repeated-index degenerates", report.unique_degenerate_repeated_index, expected.repeated_index);
    compare("unique zero-area degenerates", report.unique_degenerate_zero_area, expected.zero_area);
    compare("triangles kept", report.triangles, report.source_triangles - report.degenerate());
    if let Some(unreferenced) = expected.unreferenced_vertices {
        compare("unreferenced vertices", report.unreferenced_vertices, unreferenced);
    }
    wrong
}

#[test]
fn every_shared_scene_imports_with_its_readme_counts() {
    let Some(dir) = scenes_dir() else {
        crate::skips::skipped(crate::skips::Needs::Scenes, "every shared scene against its README counts");
        return;
    };
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let rows = expected_rows(&readme);
    assert!(rows.len() >= 50, "parsed only {} rows of the scenes README", rows.len());
    let mut failures = Vec::new();
    for row in &rows {
        let path = dir.join(&row.file);
        let result = import(Path::new(&path), &ImportOptions::default());
        // An OpenUSD stage's count is the triangles it draws with every placement expanded, degenerate ones
        // included (tests/suite/usd_oracle.rs checks the triangles themselves against usd-core).
        let usd = [".usd", ".usda", ".usdc", ".usdz"].iter().any(|e| row.file.ends_with(e));
        if usd {
            let flat = ImportOptions { instancing: Instancing::Never, keep_degenerate: true, ..Default::default() };
            match (&result, import(Path::new(&path), &flat)) {
                (Ok(_), Ok(all)) if all.soup.triangles.len() as u64 == row.triangles => {}
                (Ok(_), Ok(all)) => failures.push(format!(
                    "{}: {} triangles drawn, README {}",
                    row.file,
                    all.soup.triangles.len(),
                    row.triangles
                )),
                (Err(error), _) => failures.push(format!("{}: {error}", row.file)),
                (_, Err(error)) => failures.push(format!("{}: flattened: {error}", row.file)),
            }
            continue;
        }
        match (&result, row.draco) {
            (Err(error), true) => {
                if !error.to_string().contains("Draco") {
                    failures.push(format!("{}: the Draco error does not say Draco: {error}", row.file));
                }
            }
            (Ok(_), true) => failures.push(format!("{}: a required-Draco file imported", row.file)),
            (Err(error), false) => failures.push(format!("{}: {error}", row.file)),
            (Ok(import), false) => {
                let wrong = check(row, &import.report);
                if !wrong.is_empty() {
                    failures.push(format!("{}: {}", row.file, wrong.join("; ")));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} of {} scenes:\n{}", failures.len(), rows.len(), failures.join("\n"));
}
