//! The one table of conversion options. Every door reads it: the command line's flags (`--split-budget`, the
//! name with `-` for `_`), [`super::Settings::set`] (and with it `Conversion::set`), Python's keywords, the keys of a
//! `bvhc batch` manifest, `bvhc options --list`, and the table of `docs/cli.md`. An option's parser is written
//! once, here; what each preset sets comes from resolving the preset ([`super::resolve`]), never from a second
//! list of defaults.

use super::LeafMerge;
use super::parse::{
    BUILDERS, INSTANCING, OPACITY, OPTIMIZE_OVER, PRESETS, SELECTIONS, SPLIT_METHODS, SPLIT_TRIANGLES, count_limit,
    name_of, names, on, put, seconds,
};
use super::spec::{Kind, OptionSpec, Stage};
use super::value::OptionValue;
use crate::import::SceneSelector;
use crate::import::memory::MemoryLimit;

/// The option named `name` (or, for a `no_*` switch, its positive `inverse`).
pub fn find(name: &str) -> Option<&'static OptionSpec> {
    OPTIONS.iter().find(|o| o.name == name || o.inverse == Some(name))
}

/// Every conversion option, in the order of the command line's help.
pub static OPTIONS: &[OptionSpec] = &[
    OptionSpec {
        name: "preset",
        stage: Stage::Preset,
        kind: Kind::Choice(&names(&PRESETS)),
        value_name: "PRESET",
        help: "The option set each stage starts from (`bvhc options --preset NAME` shows it).",
        inverse: None,
        example: || "fast".into(),
        set: |s, v| put(&mut s.preset, v.choice(&PRESETS)?),
        shown: |o| o.preset.name().to_string(),
    },
    OptionSpec {
        name: "scene",
        stage: Stage::Import,
        kind: Kind::Text,
        value_name: "N|NAME",
        help: "The glTF scene to convert, by index or name.",
        inverse: None,
        example: || OptionValue::Int(0),
        set: |s, v| {
            let scene = match v {
                OptionValue::Int(_) => SceneSelector::Index(v.count()? as usize),
                _ => {
                    let text = v.text().map_err(|_| "expected a scene index or name".to_string())?;
                    text.parse::<usize>().map_or(SceneSelector::Name(text.to_string()), SceneSelector::Index)
                }
            };
            put(&mut s.overrides.scene, Some(scene))
        },
        shown: |o| match &o.import.scene {
            None => "the file's default".into(),
            Some(SceneSelector::Index(i)) => i.to_string(),
            Some(SceneSelector::Name(n)) => n.clone(),
        },
    },
    OptionSpec {
        name: "pose",
        stage: Stage::Import,
        kind: Kind::Text,
        value_name: "CLIP@SECONDS|TIME",
        help: "A glTF scene as it stands SECONDS into animation clip CLIP (index or name): node and morph weight \
               channels sampled, skins posed by the animated joints; an OpenUSD stage at time code TIME (time \
               samples interpolated).",
        inverse: None,
        example: || "0@0".into(),
        set: |s, v| {
            let pose = match v {
                OptionValue::Int(_) | OptionValue::Number(_) => crate::import::Pose::TimeCode(v.number()?),
                _ => v.text().map_err(|_| "expected a pose 'CLIP@SECONDS' or a USD time code".to_string())?.parse()?,
            };
            put(&mut s.overrides.pose, Some(pose))
        },
        shown: |o| match (&o.import.pose, o.import.time_code) {
            (Some(p), _) => format!("{:?}@{}", p.clip, p.seconds),
            (None, Some(code)) => code.to_string(),
            (None, None) => "the default pose (USD: the default time)".into(),
        },
    },
    OptionSpec {
        name: "purposes",
        stage: Stage::Import,
        kind: Kind::Text,
        value_name: "LIST",
        help: "The USD purposes whose geometry is kept besides `default` (comma-separated: render, proxy, guide).",
        inverse: None,
        example: || "render,proxy".into(),
        set: |s, v| put(&mut s.overrides.purposes, Some(v.text()?.parse()?)),
        shown: |o| o.import.purposes.to_string(),
    },
    OptionSpec {
        name: "animation",
        stage: Stage::Animation,
        kind: Kind::Text,
        value_name: "CLIPS",
        help: "Choose the tree for the scene's animation: sample poses across these clips (comma-separated indices \
               or names; every clip when none is given) and keep the tree, stored in the default pose, whose cost \
               averaged over the poses after a refit is lowest. Flattens the scene and makes no split references.",
        inverse: None,
        example: || true.into(),
        set: |s, v| {
            let clips = match v {
                OptionValue::Bool(on) => on.then(Vec::new),
                _ => Some(crate::animation::Animation::parse_clips(v.text()?)?),
            };
            put(
                &mut s.overrides.animation,
                clips.map(|clips| crate::animation::Animation { clips, ..Default::default() }),
            )
        },
        shown: |o| o.animation.as_ref().map_or("off".into(), |a| format!("{} clips", a.clips.len())),
    },
    OptionSpec {
        name: "animation_poses",
        stage: Stage::Animation,
        kind: Kind::Count,
        value_name: "N",
        help: "Poses sampled in each clip with --animation, at the middles of equal parts of its span.",
        inverse: None,
        example: || 4u32.into(),
        set: |s, v| {
            let poses = u32::try_from(v.count()?).map_err(|_| "expected a count from 1 to 64".to_string())?;
            put(&mut s.overrides.animation_poses, Some(poses))
        },
        shown: |o| {
            o.animation.as_ref().map_or(crate::animation::DEFAULT_POSES_PER_CLIP, |a| a.poses_per_clip).to_string()
        },
    },
    OptionSpec {
        name: "animation_window",
        stage: Stage::Animation,
        kind: Kind::Text,
        value_name: "START..END",
        help: "Sample only this part of each clip with --animation (seconds, START..END): a tree for the part that \
               plays, or one of several trees for the parts of a long clip, switched as it plays.",
        inverse: None,
        example: || "0..1".into(),
        set: |s, v| put(&mut s.overrides.animation_window, Some(v.text()?.parse()?)),
        shown: |o| {
            o.animation
                .as_ref()
                .and_then(|a| a.window)
                .map_or("whole clips".into(), |w| format!("{}..{}", w.start, w.end))
        },
    },
    OptionSpec {
        name: "keep_degenerate",
        stage: Stage::Import,
        kind: Kind::Switch,
        value_name: "",
        help: "Keep degenerate triangles instead of dropping them.",
        inverse: None,
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.keep_degenerate, Some(on(v)?)),
        shown: |o| o.import.keep_degenerate.to_string(),
    },
    OptionSpec {
        name: "max_input_bytes",
        stage: Stage::Import,
        kind: Kind::Count,
        value_name: "BYTES",
        help: "Import limit: bytes of any one file read, after gunzip (a USD stage's layers together).",
        inverse: None,
        example: || OptionValue::Int(1 << 29),
        set: |s, v| count_limit(s, v, |l, n| l.max_input_bytes = n),
        shown: |o| o.import.limits.max_input_bytes.to_string(),
    },
    OptionSpec {
        name: "max_triangles",
        stage: Stage::Import,
        kind: Kind::Count,
        value_name: "N",
        help: "Import limit: triangles placed (instancing multiplies), degenerate ones included.",
        inverse: None,
        example: || OptionValue::Int(1 << 20),
        set: |s, v| count_limit(s, v, |l, n| l.max_triangles = n),
        shown: |o| o.import.limits.max_triangles.to_string(),
    },
    OptionSpec {
        name: "max_decoded_values",
        stage: Stage::Import,
        kind: Kind::Count,
        value_name: "N",
        help: "Import limit: scalar values decoded (glTF accessors, OBJ and PLY vertex coordinates).",
        inverse: None,
        example: || OptionValue::Int(1 << 24),
        set: |s, v| count_limit(s, v, |l, n| l.max_decoded_values = n),
        shown: |o| o.import.limits.max_decoded_values.to_string(),
    },
    OptionSpec {
        name: "max_placements",
        stage: Stage::Import,
        kind: Kind::Count,
        value_name: "N",
        help: "Import limit: mesh placements (glTF nodes with a mesh times their GPU instances; USD instances).",
        inverse: None,
        example: || OptionValue::Int(1000),
        set: |s, v| count_limit(s, v, |l, n| l.max_placements = n),
        shown: |o| o.import.limits.max_placements.to_string(),
    },
    OptionSpec {
        name: "max_memory",
        stage: Stage::Import,
        kind: Kind::Text,
        value_name: "SIZE",
        help: "Memory the conversion may use: a size such as 8G or 512M (a whole number is bytes), or `unlimited` \
               (default: what this process may use, the smallest of available memory, its address-space limit and \
               its cgroup's limit). A scene whose estimated peak exceeds it is refused before its triangles are held.",
        inverse: None,
        example: || "8G".into(),
        set: |s, v| {
            let memory = match v {
                OptionValue::Int(_) => MemoryLimit::Bytes(v.count()?),
                _ => crate::import::memory::parse_size(v.text()?)?,
            };
            put(&mut s.overrides.limits.get_or_insert_with(Default::default).max_memory, memory)
        },
        shown: |o| match o.import.limits.max_memory {
            MemoryLimit::Detect | MemoryLimit::Detected(_) => "what this process may use".into(),
            MemoryLimit::Bytes(b) => b.to_string(),
            MemoryLimit::Unlimited => "unlimited".into(),
        },
    },
    OptionSpec {
        name: "max_polygon_vertices",
        stage: Stage::Import,
        kind: Kind::Count,
        value_name: "N",
        help: "Import limit: vertices of one OBJ or PLY polygon.",
        inverse: None,
        example: || OptionValue::Int(64),
        set: |s, v| count_limit(s, v, |l, n| l.max_polygon_vertices = n),
        shown: |o| o.import.limits.max_polygon_vertices.to_string(),
    },
    OptionSpec {
        name: "allow_outside_buffers",
        stage: Stage::Import,
        kind: Kind::Switch,
        value_name: "",
        help: "Follow glTF buffer URIs that leave the input's folder (`../`, absolute paths); off by default so that \
               an untrusted asset cannot copy other files into the output.",
        inverse: None,
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.allow_buffers_outside_input_folder, Some(on(v)?)),
        shown: |o| o.import.allow_buffers_outside_input_folder.to_string(),
    },
    OptionSpec {
        name: "instancing",
        stage: Stage::Import,
        kind: Kind::Choice(&names(&INSTANCING)),
        value_name: "POLICY",
        help: "Keep meshes placed more than once as instances in a two-level file (format 1.3): auto when their \
               extra placements add 2^20 (1,048,576) triangles or more, or the flattened scene would not fit in \
               memory (a USD stage's instances always); always (with --animation also every mesh its clips move \
               rigidly); or never (every placement flattened).",
        inverse: None,
        example: || "never".into(),
        set: |s, v| put(&mut s.overrides.instancing, Some(v.choice(&INSTANCING)?)),
        shown: |o| name_of(&INSTANCING, &o.import.instancing),
    },
    OptionSpec {
        name: "opacity",
        stage: Stage::Import,
        kind: Kind::Choice(&names(&OPACITY)),
        value_name: "WHICH",
        help: "Which triangles the file marks not opaque (format 1.5), so that a renderer's hit filter (alpha \
               testing) runs on their hits alone: those of glTF materials with alphaMode MASK or BLEND; none; or all.",
        inverse: None,
        example: || "opaque".into(),
        set: |s, v| put(&mut s.overrides.opacity, Some(v.choice(&OPACITY)?)),
        shown: |o| name_of(&OPACITY, &o.import.opacity),
    },
    OptionSpec {
        name: "builder",
        stage: Stage::Build,
        kind: Kind::Choice(&names(&BUILDERS)),
        value_name: "BUILDER",
        help: "Initial builder (without split references or with --split-method pre-split).",
        inverse: None,
        example: || "spatial-median".into(),
        set: |s, v| put(&mut s.overrides.builder, Some(v.choice(&BUILDERS)?)),
        shown: |o| name_of(&BUILDERS, &o.builder),
    },
    OptionSpec {
        name: "split_budget",
        stage: Stage::Splits,
        kind: Kind::Number,
        value_name: "FRACTION",
        help: "Cut triangles into split references where that makes the tree cheaper, at most this fraction of the \
               triangles more (0 to 4).",
        inverse: None,
        example: || 0.1.into(),
        set: |s, v| {
            let budget = v.number()?;
            if !(0.0..=crate::builders::MAX_BUDGET).contains(&budget) {
                return Err("expected a fraction from 0 to 4 (at most five references a triangle)".to_string());
            }
            put(&mut s.overrides.split_budget, Some(budget))
        },
        shown: |o| o.splits.map_or("none".into(), |s| s.budget.to_string()),
    },
    OptionSpec {
        name: "no_splits",
        stage: Stage::Splits,
        kind: Kind::Switch,
        value_name: "",
        help: "One reference a triangle: no split references, whatever the preset.",
        inverse: Some("splits"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.splits, Some(!on(v)?)),
        shown: |o| o.splits.is_none().to_string(),
    },
    OptionSpec {
        name: "split_method",
        stage: Stage::Splits,
        kind: Kind::Choice(&names(&SPLIT_METHODS)),
        value_name: "METHOD",
        help: "Where split references are cut: during the build where children overlap, or before it.",
        inverse: None,
        example: || "pre-split".into(),
        set: |s, v| put(&mut s.overrides.split_method, Some(v.choice(&SPLIT_METHODS)?)),
        shown: |o| o.splits.map_or("none".into(), |s| name_of(&SPLIT_METHODS, &s.method)),
    },
    OptionSpec {
        name: "split_triangles",
        stage: Stage::Splits,
        kind: Kind::Choice(&names(&SPLIT_TRIANGLES)),
        value_name: "WHICH",
        help: "Which triangles split references are cut from: the wasteful ones, any, or the cheaper file of both.",
        inverse: None,
        example: || "any".into(),
        set: |s, v| put(&mut s.overrides.split_triangles, Some(v.choice(&SPLIT_TRIANGLES)?)),
        shown: |o| o.splits.map_or("none".into(), |s| name_of(&SPLIT_TRIANGLES, &s.triangles)),
    },
    OptionSpec {
        name: "no_splits_deforming",
        stage: Stage::Splits,
        kind: Kind::Switch,
        value_name: "",
        help: "No split references in geometry meant to deform (glTF primitives of skinned nodes or with morph \
               targets), whose records a refit then boxes tightly; the rest of the scene may still be cut.",
        inverse: Some("splits_deforming"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.splits_deforming, Some(!on(v)?)),
        shown: |o| o.splits.map_or("none".into(), |s| (!s.deforming).to_string()),
    },
    OptionSpec {
        name: "no_optimize",
        stage: Stage::Optimize,
        kind: Kind::Switch,
        value_name: "",
        help: "Skip the optimizer (the built tree is written as built).",
        inverse: Some("optimize"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.optimize, Some(!on(v)?)),
        shown: |o| o.reinsertion.is_none().to_string(),
    },
    OptionSpec {
        name: "selection",
        stage: Stage::Optimize,
        kind: Kind::Choice(&names(&SELECTIONS)),
        value_name: "RANKING",
        help: "How the optimizer ranks nodes for reinsertion.",
        inverse: None,
        example: || "sum".into(),
        set: |s, v| put(&mut s.overrides.selection, Some(v.choice(&SELECTIONS)?)),
        shown: |o| o.optimize.selection.name().to_string(),
    },
    OptionSpec {
        name: "time_budget",
        stage: Stage::Optimize,
        kind: Kind::Number,
        value_name: "SECONDS",
        help: "Stop optimizing after this many seconds (the result then depends on the machine's speed).",
        inverse: None,
        example: || 60.0.into(),
        set: |s, v| put(&mut s.overrides.time_budget, Some(seconds(v)?)),
        shown: |o| o.optimize.time_budget.map_or("none".into(), |t| t.as_secs_f64().to_string()),
    },
    OptionSpec {
        name: "optimize_over",
        stage: Stage::Optimize,
        kind: Kind::Choice(&names(&OPTIMIZE_OVER)),
        value_name: "WHAT",
        help: "What reinsertion optimizes over: single references, the builder's subtrees of up to 4, or both with \
               the cheaper tree kept.",
        inverse: None,
        example: || "references".into(),
        set: |s, v| put(&mut s.overrides.optimize_over, Some(v.choice(&OPTIMIZE_OVER)?)),
        shown: |o| o.reinsertion.map_or("none".into(), |r| name_of(&OPTIMIZE_OVER, &r)),
    },
    OptionSpec {
        name: "max_leaf_size",
        stage: Stage::LeafLayout,
        kind: Kind::Count,
        value_name: "N",
        help: "Largest merged leaf of the binary tree.",
        inverse: None,
        example: || 4u32.into(),
        set: |s, v| {
            let n = usize::try_from(v.count()?).map_err(|_| "more than a leaf can hold".to_string())?;
            put(&mut s.overrides.max_leaf_size, Some(n))
        },
        shown: |o| o.max_leaf_size().to_string(),
    },
    OptionSpec {
        name: "no_merge",
        stage: Stage::LeafLayout,
        kind: Kind::Switch,
        value_name: "",
        help: "Keep one triangle per leaf in the binary tree (no leaf merging).",
        inverse: Some("merge_leaves"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.merge_leaves, Some(!on(v)?)),
        shown: |o| (o.leaves == LeafMerge::Off).to_string(),
    },
    OptionSpec {
        name: "no_wide",
        stage: Stage::LeafLayout,
        kind: Kind::Switch,
        value_name: "",
        help: "Omit the wide sections (8-wide nodes and triangle packets for the SIMD kernel): a format 1.0 file.",
        inverse: Some("wide"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.wide, Some(!on(v)?)),
        shown: |o| o.wide.is_none().to_string(),
    },
    OptionSpec {
        name: "tune_rays",
        stage: Stage::LeafLayout,
        kind: Kind::Count,
        value_name: "COUNT",
        help: "Tune the tree to COUNT sampled training rays (camera, ambient-occlusion and uniform rays made from \
               the scene; at most one a triangle): the leaf merge and the wide (and GPU) collapses weigh each node by \
               the rays that reach it instead of by its surface area, and the candidate trees are judged on as many \
               held-out rays. Scenes of fewer than 1024 triangles are not sampled (the file says so).",
        inverse: None,
        example: || OptionValue::Int(4096),
        set: |s, v| {
            let rays = usize::try_from(v.count()?).map_err(|_| "too many rays".to_string())?;
            put(&mut s.overrides.tune_rays, Some(rays))
        },
        shown: |o| o.ray_tuning.map_or("off".into(), |t| t.rays.to_string()),
    },
    OptionSpec {
        name: "train_rays",
        stage: Stage::LeafLayout,
        kind: Kind::Path,
        value_name: "RAYS.bin",
        help: "Tune the tree to your own rays, as --tune-rays does: a ray file of `bvhc trace` (32-byte records), \
               its even-numbered rays for training and its odd-numbered ones held out to judge the candidates. The \
               file's hash is recorded, so a changed file converts again.",
        inverse: None,
        example: || "rays.bin".into(),
        set: |s, v| {
            let path = std::path::Path::new(v.text()?);
            put(&mut s.overrides.train_rays, Some(crate::sampling::TrainingRays::read(path)?))
        },
        shown: |o| o.ray_tuning.and_then(|t| t.training_file).map_or("none".into(), |h| format!("{h:016x}")),
    },
    OptionSpec {
        name: "gpu_layout",
        stage: Stage::Output,
        kind: Kind::Switch,
        value_name: "",
        help: "Also write the GPU sections of format 1.4: compressed 8-wide nodes (80 bytes) and their leaf \
               triangles with vertices (40 bytes each), which the WGSL kernel of the loader crate traces (`bvhc \
               trace --gpu`). One-level files only.",
        inverse: None,
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.gpu_layout, Some(on(v)?)),
        shown: |o| o.gpu.is_some().to_string(),
    },
    OptionSpec {
        name: "no_ids",
        stage: Stage::Output,
        kind: Kind::Switch,
        value_name: "",
        help: "Omit the optional triangle_ids and source_table sections (and with them the source vertices).",
        inverse: Some("ids"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.write_ids, Some(!on(v)?)),
        shown: |o| (!o.write_ids).to_string(),
    },
    OptionSpec {
        name: "no_source_vertices",
        stage: Stage::Output,
        kind: Kind::Switch,
        value_name: "",
        help: "Omit the optional source_vertices section (each triangle's vertex indices in its source primitive, \
               for interpolating the source's normals and texture coordinates; 12 bytes a triangle). Without it and \
               without the wide sections the file is version 1.0.",
        inverse: Some("source_vertices"),
        example: || true.into(),
        set: |s, v| put(&mut s.overrides.write_source_vertices, Some(!on(v)?)),
        shown: |o| (!o.write_source_vertices).to_string(),
    },
];
