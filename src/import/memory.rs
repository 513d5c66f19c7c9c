//! The memory a conversion may use, and what a scene will need. A conversion's peak grows with the triangles it
//! places, so the importer refuses a scene whose estimated peak exceeds the budget before it holds the
//! triangles (for glTF before it decodes any: placements times mesh sizes are known from the JSON), with an error
//! that names the estimate and the option that raises the budget.
//!
//! The estimate is [`BASE_BYTES`] plus bytes a triangle, fitted to the peak resident memory of conversions
//! (`/usr/bin/time -f %M`, 2 threads) and rounded up, so that it errs towards refusing: default conversions of
//! the 871k-triangle dragon 292-329 MB (263 bytes a triangle above the base), the 232k-triangle kitchen 137 MB,
//! the 7.8M-triangle dragon grid 1,848 MB (224 bytes a triangle; `docs/scale.md`). Conversions that compare
//! candidate trees (`choose`, the max-quality preset) hold more than one: the dragon with max-quality 440 MB
//! (390 bytes a triangle), the grid with `--optimize-over choose` 2.45 GB against 1.79 GB.

use serde::Serialize;

/// Bytes a conversion needs whatever its size (the program, its threads, the input's buffers).
pub const BASE_BYTES: u64 = 100 << 20;

/// Bytes a placed triangle needs at the peak of a conversion that builds one tree: the soup, the build's
/// references, the optimizer's tree, the packed arrays (the file is streamed).
pub const BYTES_PER_TRIANGLE: u64 = 270;

/// Bytes a triangle adds to the peak when the conversion also writes the GPU sections (format 1.4): the GPU
/// collapse beside the wide one, the packed nodes and 40-byte leaf triangles, and their pages in the verified
/// output (the dragon, 871k triangles: a 300 MB peak without them, 452 MB with them).
pub const GPU_LAYOUT_BYTES_PER_TRIANGLE: u64 = 180;

/// Bytes a placed triangle needs at the peak of a conversion that compares candidate trees.
pub const BYTES_PER_TRIANGLE_WITH_CANDIDATES: u64 = 400;

/// How much memory a conversion may use ([`super::ImportLimits::max_memory`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MemoryLimit {
    /// What the process may use when the import starts: [`usable_memory`].
    Detect,
    /// At most this many bytes, as given (`--max-memory`).
    Bytes(u64),
    /// At most this many bytes, as [`MemoryLimit::Detect`] found when the import started.
    Detected(u64),
    /// No check.
    Unlimited,
}

impl MemoryLimit {
    /// The budget in bytes, `None` for no check (unlimited, or nothing could be read).
    pub fn budget(self) -> Option<u64> {
        // Detect reads the system each time; the importer resolves it once to `Detected`.
        match self {
            MemoryLimit::Detect => usable_memory(),
            MemoryLimit::Bytes(bytes) | MemoryLimit::Detected(bytes) => Some(bytes),
            MemoryLimit::Unlimited => None,
        }
    }

    /// Refuses `triangles` placed triangles whose conversion needs more than the budget at `bytes_per_triangle`.
    pub fn check(self, triangles: u64, bytes_per_triangle: u64) -> Result<(), String> {
        self.check_with(triangles, bytes_per_triangle, 0)
    }

    /// [`MemoryLimit::check`] for a conversion whose import also holds `decoded_bytes` of decoded input (a glTF's
    /// accessors: a file can declare many vertices for few triangles).
    pub fn check_with(self, triangles: u64, bytes_per_triangle: u64, decoded_bytes: u64) -> Result<(), String> {
        let Some(budget) = self.budget() else { return Ok(()) };
        let needed =
            BASE_BYTES.saturating_add(triangles.saturating_mul(bytes_per_triangle)).saturating_add(decoded_bytes);
        if needed <= budget {
            return Ok(());
        }
        let source = match self {
            MemoryLimit::Bytes(_) => "--max-memory allows",
            _ => "this process may use (available memory, address-space and cgroup limits)",
        };
        let decoded = match decoded_bytes {
            0 => String::new(),
            bytes => format!(" + {} of decoded accessors", size(bytes)),
        };
        Err(format!(
            "{triangles} placed triangles need about {} to convert ({} + {bytes_per_triangle} bytes a triangle{decoded}), \
             more than the {} {source} (raise the budget with --max-memory, e.g. --max-memory {})",
            size(needed),
            size(BASE_BYTES),
            size(budget),
            size(needed.saturating_add(needed / 8)),
        ))
    }
}

/// A byte count for people: `1.5G`, `640M`, `12K`, the units `--max-memory` reads.
pub fn size(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 => format!("{:.1}G", b as f64 / f64::from(1u32 << 30)),
        b if b >= 1 << 20 => format!("{}M", b.div_ceil(1 << 20)),
        b => format!("{}K", b.div_ceil(1 << 10)),
    }
}

/// Parses a byte count: a number with an optional K, M, G or T suffix (powers of 1024), or `unlimited`.
pub fn parse_size(text: &str) -> Result<MemoryLimit, String> {
    let text = text.trim();
    if text.eq_ignore_ascii_case("unlimited") {
        return Ok(MemoryLimit::Unlimited);
    }
    let (digits, shift) = match text.as_bytes().last().map(u8::to_ascii_uppercase) {
        Some(b'K') => (&text[..text.len() - 1], 10),
        Some(b'M') => (&text[..text.len() - 1], 20),
        Some(b'G') => (&text[..text.len() - 1], 30),
        Some(b'T') => (&text[..text.len() - 1], 40),
        _ => (text, 0),
    };
    let value: f64 =
        digits.trim().parse().map_err(|_| format!("'{text}': expected a size such as 8G, 512M or unlimited"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < 2f64.powi(64)) {
        return Err(format!("'{text}': a size from 1 byte to 16 EiB, or unlimited"));
    }
    Ok(MemoryLimit::Bytes(bytes as u64))
}

/// The memory this process may use: the smallest of the available memory (`MemAvailable`), the room left under
/// its address-space limit and under its cgroup's memory limit; `None` where none of them can be read.
pub fn usable_memory() -> Option<u64> {
    [available_memory(), address_space_room(), cgroup_room()].into_iter().flatten().min()
}

/// A `Name:   123 kB` field of a `/proc` status file, in bytes.
fn kib_field(text: &str, field: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(field))?;
    let kib: u64 = line[field.len()..].trim().trim_end_matches("kB").trim().parse().ok()?;
    kib.checked_mul(1024)
}

fn available_memory() -> Option<u64> {
    kib_field(&std::fs::read_to_string("/proc/meminfo").ok()?, "MemAvailable:")
}

/// The address-space limit (`Max address space` in `/proc/self/limits`) minus what the process maps now.
fn address_space_room() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits.lines().find(|l| l.starts_with("Max address space"))?;
    let soft: u64 = line["Max address space".len()..].split_whitespace().next()?.parse().ok()?;
    let mapped = kib_field(&std::fs::read_to_string("/proc/self/status").ok()?, "VmSize:").unwrap_or(0);
    Some(soft.saturating_sub(mapped))
}

/// cgroup v2's `memory.max` minus `memory.current` for this process's group.
fn cgroup_room() -> Option<u64> {
    let group = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = group.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim().trim_start_matches('/'));
    let max: u64 = std::fs::read_to_string(dir.join("memory.max")).ok()?.trim().parse().ok()?;
    let current: u64 = std::fs::read_to_string(dir.join("memory.current")).ok()?.trim().parse().ok()?;
    Some(max.saturating_sub(current))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_print() {
        assert_eq!(parse_size("8G"), Ok(MemoryLimit::Bytes(8 << 30)));
        assert_eq!(parse_size("512m"), Ok(MemoryLimit::Bytes(512 << 20)));
        assert_eq!(parse_size("1.5K"), Ok(MemoryLimit::Bytes(1536)));
        assert_eq!(parse_size("4096"), Ok(MemoryLimit::Bytes(4096)));
        assert_eq!(parse_size("unlimited"), Ok(MemoryLimit::Unlimited));
        for bad in ["", "G", "-1G", "0", "nan", "1e30T", "8X"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(size(3 << 30), "3.0G");
        assert_eq!(size(640 << 20), "640M");
    }

    #[test]
    fn the_check_names_the_estimate_and_the_option() {
        let limit = MemoryLimit::Bytes(1 << 30);
        assert!(limit.check(1_000_000, BYTES_PER_TRIANGLE).is_ok());
        let error = limit.check(42_000_000, BYTES_PER_TRIANGLE).unwrap_err();
        assert!(error.contains("42000000 placed triangles need about 10.7G"), "{error}");
        assert!(error.contains("--max-memory"), "{error}");
        assert!(MemoryLimit::Unlimited.check(u64::MAX, u64::MAX).is_ok());
        let detected = MemoryLimit::Detected(1 << 30).check(42_000_000, BYTES_PER_TRIANGLE).unwrap_err();
        assert!(detected.contains("this process may use") && detected.contains("--max-memory"), "{detected}");
    }

    #[test]
    fn this_machine_reports_some_usable_memory() {
        if std::fs::metadata("/proc/meminfo").is_err() {
            eprintln!("SKIPPED: no /proc/meminfo on this system");
            return;
        }
        let usable = usable_memory().expect("MemAvailable is readable");
        assert!(usable > 1 << 20, "{usable}");
    }
}
