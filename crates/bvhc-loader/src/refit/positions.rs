//! The new positions a refit takes ([`RefitPositions`]): checked against the file before anything is written,
//! then written into the triangle records leaf by leaf as the binary tree's refit walks them
//! ([`NewRecords`]).

use crate::binary::refit::NewRecords;
use crate::error::Error;
use crate::format::{Bounds, PackedTriangle, SourceRange, SourceVertexIndices, TriangleFold};

/// Where a refit's triangles move to, in the file's space (the space of its triangle records: for a glTF scene
/// the world space after each node's transform, which is what skinning produces).
#[derive(Clone, Copy, Debug)]
pub enum RefitPositions<'a> {
    /// One triangle a record, in record order (`v0`, `v1`, `v2` as [`crate::BvhView::triangles`] holds them).
    Triangles(&'a [[[f32; 3]; 3]]),
    /// Per source range (the ranges of [`crate::BvhView::source_table`], in order), the positions of its primitive's
    /// vertices indexed as the source primitive indexes them (the indices of the `source_vertices` section,
    /// [`crate::BvhView::source_corners`]), or `None` to leave that range's records where they are. What a skinning or
    /// morphing pass produces for each mesh primitive. Needs a file written with source vertices (bvhc's
    /// default).
    SourceVertices(&'a [Option<&'a [[f32; 3]]>]),
}

/// How each record finds its new vertices: the positions with the sections that map source vertices to records.
pub(crate) enum MovedRecords<'a> {
    Triangles(&'a [[[f32; 3]; 3]]),
    SourceVertices {
        positions: &'a [Option<&'a [[f32; 3]]>],
        ranges: &'a [SourceRange],
        ids: &'a [u32],
        corners: &'a [SourceVertexIndices],
    },
}

impl<'a> MovedRecords<'a> {
    /// `positions` read through the file's `source_table`, `triangle_ids` and `source_vertices` sections (`None`
    /// for a section the file lacks, which positions per source vertex refuse).
    pub(crate) fn new(
        positions: RefitPositions<'a>,
        ranges: Option<&'a [SourceRange]>,
        ids: Option<&'a [u32]>,
        corners: Option<&'a [SourceVertexIndices]>,
    ) -> Result<MovedRecords<'a>, Error> {
        match positions {
            RefitPositions::Triangles(triangles) => Ok(MovedRecords::Triangles(triangles)),
            RefitPositions::SourceVertices(positions) => match (ranges, ids, corners) {
                (Some(ranges), Some(ids), Some(corners)) => {
                    Ok(MovedRecords::SourceVertices { positions, ranges, ids, corners })
                }
                _ => Err(Error::Refit(
                    "positions per source vertex need the file's source_vertices section (convert without \
                     --no-source-vertices)"
                        .into(),
                )),
            },
        }
    }

    /// Checks the positions against the file's `record_count` records (counts, finite coordinates, source
    /// vertex indices in range), naming the record, range or vertex at fault.
    pub(crate) fn check(&self, record_count: usize) -> Result<(), Error> {
        match self {
            MovedRecords::Triangles(triangles) => {
                if triangles.len() != record_count {
                    let count = triangles.len();
                    return Err(Error::Refit(format!("{count} positions for {record_count} triangle records")));
                }
                if !all_finite(triangles.as_flattened().as_flattened()) {
                    let record = triangles.iter().position(|t| !all_finite(t.as_flattened())).unwrap_or(0);
                    return Err(Error::Refit(format!("triangle record {record}: a coordinate that is not finite")));
                }
            }
            MovedRecords::SourceVertices { positions, ranges, ids, .. } => {
                if positions.len() != ranges.len() {
                    let (given, count) = (positions.len(), ranges.len());
                    return Err(Error::Refit(format!("positions for {given} source ranges, but the file has {count}")));
                }
                for (range, vertices) in positions.iter().enumerate() {
                    let Some(vertices) = vertices.filter(|v| !all_finite(v.as_flattened())) else { continue };
                    if let Some(vertex) = vertices.iter().position(|v| !all_finite(v)) {
                        return Err(Error::Refit(format!(
                            "source range {range}, vertex {vertex}: a coordinate that is not finite"
                        )));
                    }
                }
                let (mut last_range, mut last_kept) = (0, 0);
                for record in 0..record_count {
                    // The fast lookups first: a record of a range left where it is, or one that moves; where they
                    // find nothing, the record is at fault.
                    let id = ids.get(record).copied().unwrap_or(u32::MAX);
                    if range_holding(ranges, id, &mut last_range).is_some_and(|r| positions[r].is_none()) {
                        continue;
                    }
                    if self.moved(record, &mut last_range).is_some() {
                        continue;
                    }
                    if let Err(why) = self.record(record, &mut last_kept) {
                        return Err(Error::Refit(format!("triangle record {record}: {why}")));
                    }
                }
            }
        }
        Ok(())
    }

    /// Whether any of `records` moves: always with positions per record; per source vertex, whether a record's
    /// range is given positions (a record in no range counts as moving: the checks refuse it).
    pub(crate) fn moves_any(&self, records: std::ops::Range<usize>) -> bool {
        match self {
            MovedRecords::Triangles(_) => true,
            MovedRecords::SourceVertices { positions, ranges, ids, .. } => {
                let mut last_range = 0;
                ids.get(records).unwrap_or(&[]).iter().any(|&id| {
                    range_holding(ranges, id, &mut last_range)
                        .is_none_or(|r| positions.get(r).is_some_and(Option::is_some))
                })
            }
        }
    }

    /// The new vertices of `record` where it moves, as [`MovedRecords::record`] finds them, without saying why a
    /// record stays (the refit's own path: checked before, so `None` means the record keeps its vertices).
    #[inline(always)]
    fn moved(&self, record: usize, last_range: &mut usize) -> Option<[[f32; 3]; 3]> {
        match self {
            MovedRecords::Triangles(triangles) => triangles.get(record).copied(),
            MovedRecords::SourceVertices { positions, ranges, ids, corners } => {
                let range = range_holding(ranges, *ids.get(record)?, last_range)?;
                let vertices = (*positions.get(range)?)?;
                let indices = corners.get(record)?.indices;
                Some([
                    *vertices.get(indices[0] as usize)?,
                    *vertices.get(indices[1] as usize)?,
                    *vertices.get(indices[2] as usize)?,
                ])
            }
        }
    }

    /// The new vertices of `record`, `None` where the record stays; an error saying why a record cannot move.
    /// `last_range` carries the range of the record before (records of one primitive often follow each other),
    /// tried before a search.
    pub(super) fn record(&self, record: usize, last_range: &mut usize) -> Result<Option<[[f32; 3]; 3]>, String> {
        match self {
            MovedRecords::Triangles(triangles) => Ok(triangles.get(record).copied()),
            MovedRecords::SourceVertices { positions, ranges, ids, corners } => {
                let id = ids.get(record).copied().ok_or("no source id")?;
                let range = range_holding(ranges, id, last_range)
                    .ok_or_else(|| format!("source id {id} lies in no source range"))?;
                let Some(vertices) = positions[range] else { return Ok(None) };
                let indices = corners.get(record).ok_or("no source vertices")?.indices;
                let vertex = |k: usize| {
                    vertices.get(indices[k] as usize).copied().ok_or_else(|| {
                        format!(
                            "source vertex {} of source range {range}, but {} positions were given for it",
                            indices[k],
                            vertices.len()
                        )
                    })
                };
                Ok(Some([vertex(0)?, vertex(1)?, vertex(2)?]))
            }
        }
    }

    /// Checks that the records of one source id (a split triangle's references) move to the same positions,
    /// naming the first two records that do not. Positions per source vertex always agree (V40: one id, one set
    /// of source vertices).
    pub(crate) fn check_references_agree(&self, ids: &[u32]) -> Result<(), Error> {
        let MovedRecords::Triangles(triangles) = self else { return Ok(()) };
        let id_count = ids.iter().map(|&id| id as usize + 1).max().unwrap_or(0);
        let mut first_record = vec![u32::MAX; id_count];
        for (record, &id) in ids.iter().enumerate() {
            let Some(first) = first_record.get_mut(id as usize) else { continue };
            if *first == u32::MAX {
                *first = record as u32;
            } else if triangles[*first as usize]
                .as_flattened()
                .iter()
                .map(|c| c.to_bits())
                .ne(triangles[record].as_flattened().iter().map(|c| c.to_bits()))
            {
                return Err(Error::Refit(format!(
                    "triangle records {} and {record} are references of one triangle (source id {id}) given \
                     different positions",
                    *first
                )));
            }
        }
        Ok(())
    }
}

/// The source range holding `id`: `last_range` (the range of the record before: records of one primitive often
/// follow each other) when it does, else the one a search finds, which becomes `last_range`; `None` when no range
/// holds it.
#[inline(always)]
fn range_holding(ranges: &[SourceRange], id: u32, last_range: &mut usize) -> Option<usize> {
    let holds =
        |r: usize| ranges.get(r).is_some_and(|r| id.wrapping_sub(r.first_source_triangle) < r.source_triangle_count);
    if !holds(*last_range) {
        *last_range = ranges.partition_point(|r| r.first_source_triangle <= id).checked_sub(1).filter(|&r| holds(r))?;
    }
    Some(*last_range)
}

/// Positions per record, in record order.
impl NewRecords for [[[f32; 3]; 3]] {
    #[inline(always)]
    fn write(&self, first: usize, records: &mut [PackedTriangle]) -> Bounds {
        let mut fold = TriangleFold::EMPTY;
        for (record, vertices) in records.iter_mut().zip(self.get(first..).unwrap_or(&[])) {
            record.vertices = *vertices;
            fold.add(vertices);
        }
        fold.bounds()
    }
}

impl NewRecords for MovedRecords<'_> {
    fn write(&self, first: usize, records: &mut [PackedTriangle]) -> Bounds {
        match self {
            MovedRecords::Triangles(triangles) => triangles.write(first, records),
            MovedRecords::SourceVertices { .. } => {
                let mut fold = TriangleFold::EMPTY;
                let mut last_range = 0;
                for (k, record) in records.iter_mut().enumerate() {
                    // Checked before: every record has its vertices (or stays).
                    match self.moved(first + k, &mut last_range) {
                        Some(vertices) => {
                            record.vertices = vertices;
                            fold.add(&vertices);
                        }
                        None => fold.add(&record.vertices),
                    }
                }
                fold.bounds()
            }
        }
    }
}

/// Whether every coordinate is finite: its exponent bits not all set (a fold without an early exit, which
/// vectorizes: a refit checks every coordinate of a file's worth of positions before writing any).
fn all_finite(coordinates: &[f32]) -> bool {
    const EXPONENT: u32 = 0x7f80_0000;
    !coordinates.iter().fold(false, |bad, c| bad | (c.to_bits() & EXPONENT == EXPONENT))
}
