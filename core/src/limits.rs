//! Every numeric limit lumis enforces on its input, in one place. docs/robustness.md states why
//! each has its value; the scene loader, the parameter checks and the CLI enforce them.

use std::fmt::Write as _;
use std::sync::OnceLock;

/// Largest magnitude of any scene coordinate: vertices and sphere extents after their
/// transforms, the camera, point lights. Within it, products of three coordinate differences
/// (the watertight triangle test's `t`, ≤ 8e36) and the BVH's surface-area costs (3·(2e12)² per
/// node times the primitive count, ≤ 1e34 for 2³² primitives) stay far below f32's 3.4e38; at
/// about 1e19 the BVH builder's costs overflow (obvhs then panics).
pub const MAX_COORDINATE: f32 = 1e12;

/// Smallest size of a shape: the diagonal of a mesh's bounding box, a sphere's radius. Above it
/// the cube of a length (≥ 1e-30, the triangle test's `t` before division) and its rounding
/// error bound (γ₃ times that, ≥ 1e-37) stay normal f32 numbers; below about 2e-13 they
/// underflow and the error bounds that keep rays from re-hitting their own surface vanish.
pub const MIN_SHAPE_SIZE: f32 = 1e-10;

/// Largest emitted radiance, intensity or irradiance, per channel, as written in a scene or read
/// from an environment map.
pub const MAX_EMISSION: f32 = 1e12;

/// Largest `scale` of an emitter. With [`MAX_EMISSION`], what an emitter emits stays at or below
/// 1e18 per channel: 20 orders of magnitude below f32's largest number for the BSDF values,
/// cosines, inverse densities and MIS weights that multiply it in a sample, and a squared
/// one-sample estimate (the sampling-variance AOV) that stays finite in f64.
pub const MAX_EMITTER_SCALE: f32 = 1e6;

/// Largest film width or height, in pixels.
pub const MAX_FILM_SIDE: u32 = 1 << 16;

/// Formats a number for messages: plain when moderate, in scientific notation when huge or tiny.
pub fn fmt_number(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// As [`fmt_number`], with the shortest digits that identify an f32 (1e12, not 999999995904).
pub fn fmt_f32(v: f32) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// "(x, y, z)", each as [`fmt_f32`] writes it.
pub fn fmt_f32s(values: &[f32]) -> String {
    let items: Vec<String> = values.iter().map(|&v| fmt_f32(v)).collect();
    format!("({})", items.join(", "))
}

/// Formats a byte count as "51.5 GB" (decimal units, as `free -h` does not but disks do; the
/// figure is an estimate, three digits suffice).
pub fn fmt_bytes(bytes: u64) -> String {
    let mut s = String::new();
    let b = bytes as f64;
    let _ = match bytes {
        0..1_000 => write!(s, "{bytes} bytes"),
        1_000..1_000_000 => write!(s, "{:.1} kB", b / 1e3),
        1_000_000..1_000_000_000 => write!(s, "{:.1} MB", b / 1e6),
        1_000_000_000..1_000_000_000_000 => write!(s, "{:.1} GB", b / 1e9),
        _ => write!(s, "{:.1} TB", b / 1e12),
    };
    s
}

/// Parses a memory size: bytes, or a number with a unit K, M, G, T (powers of 1000; KiB, MiB,
/// GiB, TiB for powers of 1024), e.g. `8G`, `512MiB`, `1.5G`.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("`{text}` is not a memory size such as 8G or 512M"))?;
    let factor: f64 = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 1.0,
        "K" | "KB" => 1e3,
        "M" | "MB" => 1e6,
        "G" | "GB" => 1e9,
        "T" | "TB" => 1e12,
        "KIB" => 1024.0,
        "MIB" => 1024f64.powi(2),
        "GIB" => 1024f64.powi(3),
        "TIB" => 1024f64.powi(4),
        _ => {
            return Err(format!(
                "`{text}`: unknown unit `{unit}` (use K, M, G or T)"
            ));
        }
    };
    let bytes = value * factor;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("`{text}` is not a usable memory size"));
    }
    Ok(bytes as u64)
}

/// How much memory a scene may use, and where that figure comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryLimit {
    /// `None`: no limit (set so, or nothing to derive one from).
    pub bytes: Option<u64>,
    /// Where the figure comes from, for messages.
    pub source: String,
}

static LIMIT_OVERRIDE: OnceLock<MemoryLimit> = OnceLock::new();

/// Environment variable that sets the memory limit: a size (`8G`) or `none`.
pub const MEMORY_LIMIT_VARIABLE: &str = "LUMIS_MEMORY_LIMIT";

/// Sets the limit for the rest of the process (the CLI's `--memory-limit`); `text` as for
/// [`MEMORY_LIMIT_VARIABLE`]. Only the first call counts.
pub fn set_memory_limit(text: &str, source: &str) -> Result<(), String> {
    let bytes = match text.trim() {
        "none" => None,
        t => Some(parse_bytes(t)?),
    };
    let _ = LIMIT_OVERRIDE.set(MemoryLimit {
        bytes,
        source: source.to_string(),
    });
    Ok(())
}

/// The limit in force: [`set_memory_limit`], else `LUMIS_MEMORY_LIMIT`, else the memory the
/// kernel says is available (`MemAvailable` in /proc/meminfo, which counts free memory and
/// reclaimable caches), else none.
pub fn memory_limit() -> Result<MemoryLimit, String> {
    if let Some(limit) = LIMIT_OVERRIDE.get() {
        return Ok(limit.clone());
    }
    if let Ok(text) = std::env::var(MEMORY_LIMIT_VARIABLE) {
        let bytes = match text.trim() {
            "none" => None,
            t => Some(parse_bytes(t).map_err(|e| format!("{MEMORY_LIMIT_VARIABLE}: {e}"))?),
        };
        return Ok(MemoryLimit {
            bytes,
            source: MEMORY_LIMIT_VARIABLE.to_string(),
        });
    }
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| mem_available(&text));
    Ok(match available {
        Some(bytes) => MemoryLimit {
            bytes: Some(bytes),
            source: "the memory available (MemAvailable in /proc/meminfo)".into(),
        },
        None => MemoryLimit {
            bytes: None,
            source: "no limit (/proc/meminfo is not readable)".into(),
        },
    })
}

/// `MemAvailable` of /proc/meminfo, in bytes.
fn mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_whitespace().skip(1);
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        None => Some(value),
        Some(_) => None,
    }
}

/// An estimate of the memory a render needs, by part, to compare with the limit before anything
/// large is allocated.
#[derive(Clone, Debug, Default)]
pub struct MemoryEstimate {
    parts: Vec<(String, u64)>,
}

impl MemoryEstimate {
    pub fn add(&mut self, what: impl Into<String>, bytes: u64) {
        self.parts.push((what.into(), bytes));
    }

    pub fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0u64, |sum, (_, b)| sum.saturating_add(*b))
    }

    /// Fails, with the figure, its parts and the limit, when the estimate exceeds the limit.
    pub fn check(&self, limit: &MemoryLimit) -> Result<(), String> {
        let total = self.total();
        let Some(bytes) = limit.bytes.filter(|&b| total > b) else {
            return Ok(());
        };
        let parts: Vec<String> = self
            .parts
            .iter()
            .filter(|(_, b)| *b > 0)
            .map(|(what, b)| format!("{what}: {}", fmt_bytes(*b)))
            .collect();
        Err(format!(
            "the render would need about {} ({}), more than the {} allowed by {}; set {} \
             (or `lumis render --memory-limit`) to a size such as 64G, or to `none`, to change the limit",
            fmt_bytes(total),
            parts.join(", "),
            fmt_bytes(bytes),
            limit.source,
            MEMORY_LIMIT_VARIABLE
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_print() {
        assert_eq!(parse_bytes("8G"), Ok(8_000_000_000));
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5 GB"), Ok(1_500_000_000));
        assert_eq!(parse_bytes("4096"), Ok(4096));
        assert!(parse_bytes("8X").is_err());
        assert!(parse_bytes("-3G").is_err());
        assert!(parse_bytes("").is_err());
        assert_eq!(fmt_bytes(51_539_607_552), "51.5 GB");
        assert_eq!(fmt_bytes(999), "999 bytes");
        assert_eq!(fmt_number(1e23), "1e23");
        assert_eq!(fmt_number(0.25), "0.25");
        assert_eq!(fmt_f32(MAX_COORDINATE), "1e12");
        assert_eq!(fmt_f32(-1e19), "-1e19");
        assert_eq!(fmt_f32(3.5), "3.5");
    }

    #[test]
    fn meminfo_is_read_in_kilobytes() {
        let text = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   22000000 kB\n";
        assert_eq!(mem_available(text), Some(22_000_000 * 1024));
        assert_eq!(mem_available("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn estimates_above_the_limit_are_refused_with_their_parts() {
        let mut e = MemoryEstimate::default();
        e.add("film 65536x65536", 51_539_607_552);
        e.add("geometry", 0);
        let limit = MemoryLimit {
            bytes: Some(22_000_000_000),
            source: "a test".into(),
        };
        let msg = e.check(&limit).unwrap_err();
        assert!(
            msg.contains("about 51.5 GB (film 65536x65536: 51.5 GB)")
                && msg.contains("22.0 GB allowed by a test"),
            "{msg}"
        );
        assert!(
            e.check(&MemoryLimit {
                bytes: None,
                source: String::new()
            })
            .is_ok()
        );
    }
}
