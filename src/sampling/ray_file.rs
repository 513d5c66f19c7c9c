//! Ray files (`format-spec/rays-and-hits.md`): what `bvhc trace` reads and `--train-rays` trains on.

use bvhc_loader::Ray;

/// Bytes of one ray record.
pub const RAY_RECORD_BYTE_LEN: usize = 32;
/// Parses ray records; the error names the first bad ray and the rule it breaks.
pub fn parse_rays(bytes: &[u8]) -> Result<Vec<Ray>, String> {
    if !bytes.len().is_multiple_of(RAY_RECORD_BYTE_LEN) {
        return Err(format!("{} bytes is not a whole number of {RAY_RECORD_BYTE_LEN}-byte ray records", bytes.len()));
    }
    let mut rays = Vec::new();
    rays.try_reserve_exact(bytes.len() / RAY_RECORD_BYTE_LEN).map_err(|_| "out of memory for the rays".to_string())?;
    for (i, record) in bytes.chunks_exact(RAY_RECORD_BYTE_LEN).enumerate() {
        let f: [f32; 8] = std::array::from_fn(|k| {
            f32::from_le_bytes([record[4 * k], record[4 * k + 1], record[4 * k + 2], record[4 * k + 3]])
        });
        let ray = Ray { origin: [f[0], f[1], f[2]], direction: [f[3], f[4], f[5]], t_min: f[6], t_max: f[7] };
        if let Err(error) = ray.check() {
            return Err(format!("ray {i}: {error}"));
        }
        rays.push(ray);
    }
    Ok(rays)
}

/// The ray file's bytes: a regular file only.
pub fn read_ray_file(path: &std::path::Path) -> Result<Vec<u8>, String> {
    let metadata = std::fs::metadata(path).map_err(|e| format!("cannot read: {e}"))?;
    if !metadata.is_file() {
        return Err("cannot read: not a regular file".to_string());
    }
    std::fs::read(path).map_err(|e| format!("cannot read: {e}"))
}

/// A user's training rays (`--train-rays FILE`): the rays and the XXH3-64 of the file's bytes, which the
/// metadata records (`build.ray_tuning.training_file`), so a changed file makes the output out of date.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainingRays {
    /// The rays, in file order.
    pub rays: std::sync::Arc<[Ray]>,
    /// XXH3-64 (seed 0) of the file's bytes.
    pub content_hash: u64,
}

impl TrainingRays {
    /// Reads and checks a ray file; the error names the file and, for a bad record, the ray and the rule.
    pub fn read(path: &std::path::Path) -> Result<TrainingRays, String> {
        let bytes = read_ray_file(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let rays = parse_rays(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        if rays.is_empty() {
            return Err(format!("{}: no rays to train on", path.display()));
        }
        Ok(TrainingRays { rays: rays.into(), content_hash: xxhash_rust::xxh3::xxh3_64(&bytes) })
    }
}
