//! A scene's reference image: a user's EXR, or the study's baseline (the balance heuristic, or
//! `path` with it) rendered as independent seed shards (cells of the plan) and merged, with each pixel's own variance from the spread of
//! the shards. Rendered references are cached in the cache directory under a key made of
//! everything that changes the image: the scene file and the files it names, the overrides, the
//! sample count and shards, and the program itself (a hash of the executable).

use super::cell::CellResult;
use super::plan::ReferencePlan;
use anyhow::{Context, Result, bail};
use lumis_core::film::Film;
use lumis_core::image_io::{self, Metadata};
use lumis_core::math::{Rgb, luminance};
use lumis_core::output::{Aov, Window};
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The layer of a cached reference holding each pixel's variance (of its luminance's mean).
const VARIANCE_LAYER: &str = "reference_variance";
const VARIANCE_CHANNEL: &str = "Y";

/// The reference image of a scene and the variance of its pixels' estimates (when known).
#[derive(Clone, Debug)]
pub struct Reference {
    pub pixels: Vec<Rgb>,
    /// Luminance of each pixel.
    pub luminance: Vec<f64>,
    /// The variance of each pixel's luminance estimate (0 for a user's file, which states none).
    pub variance: Vec<f64>,
    /// Samples per light per pixel (camera samples per pixel for `path`), when rendered.
    pub samples: Option<u32>,
    /// CPU seconds it took, when rendered (by this run or the cached one's).
    pub cpu_time: Option<f64>,
    pub path: PathBuf,
    pub cached: bool,
}

impl Reference {
    fn new(pixels: Vec<Rgb>, variance: Vec<f64>, path: PathBuf) -> Self {
        Reference {
            luminance: pixels.iter().map(|&c| luminance(c) as f64).collect(),
            pixels,
            variance,
            samples: None,
            cpu_time: None,
            path,
            cached: false,
        }
    }

    /// The mean over pixels of the reference's own variance.
    pub fn mean_variance(&self) -> f64 {
        self.variance.iter().sum::<f64>() / self.variance.len().max(1) as f64
    }

    /// Standard error of the reference's mean luminance.
    pub fn mean_standard_error(&self) -> f64 {
        let p = self.variance.len().max(1) as f64;
        (self.variance.iter().sum::<f64>() / (p * p)).sqrt()
    }
}

/// Reads a reference EXR the user gave for a scene of `window`'s size.
pub fn read_file(file: &Path, window: Window) -> Result<Reference> {
    let pixels = (window.width * window.height) as usize;
    let channels = image_io::read_exr_channels(file).map_err(anyhow::Error::msg)?;
    let channel = |name: &str| channels.iter().find(|(n, _)| n == name).map(|(_, v)| v);
    let (Some(r), Some(g), Some(b)) = (channel("R"), channel("G"), channel("B")) else {
        bail!("reference `{}` has no R, G, B channels", file.display());
    };
    if r.len() != pixels {
        bail!(
            "reference `{}` has {} pixels, the scene renders {pixels} ({}×{})",
            file.display(),
            r.len(),
            window.width,
            window.height
        );
    }
    let variance = channel(&format!("{VARIANCE_LAYER}.{VARIANCE_CHANNEL}")).map_or_else(
        || vec![0.0; pixels],
        |v| v.iter().map(|&v| v as f64).collect(),
    );
    Ok(Reference::new(
        (0..pixels).map(|i| Rgb::new(r[i], g[i], b[i])).collect(),
        variance,
        file.to_path_buf(),
    ))
}

/// Where a scene's rendered reference is cached, and the key that identifies it.
pub struct CacheEntry {
    pub file: PathBuf,
    pub key: String,
}

/// The cache entry of a scene's reference rendered as `plan` says.
pub fn cache_entry(
    cache_dir: &Path,
    scene: &Path,
    name: &str,
    window: Window,
    overrides: &[String],
    plan: &ReferencePlan,
) -> Result<CacheEntry> {
    let key = key(scene, overrides, plan)?;
    let file = cache_dir.join(format!(
        "{name}-{}x{}-{}-{key}.exr",
        window.width,
        window.height,
        plan.total_samples()
    ));
    Ok(CacheEntry { file, key })
}

/// The cached reference, if there is one with this key.
pub fn cached(entry: &CacheEntry, window: Window, plan: &ReferencePlan) -> Option<Reference> {
    let metadata = image_io::read_exr_metadata(&entry.file).ok()?;
    let value = |k: &str| {
        metadata
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.clone())
    };
    if value("key")? != entry.key {
        return None;
    }
    let mut reference = read_file(&entry.file, window).ok()?;
    reference.samples = Some(plan.total_samples());
    reference.cpu_time = value("cpu_time").and_then(|v| v.parse().ok());
    reference.cached = true;
    Some(reference)
}

/// Merges the shards' renders into the reference (their mean, and each pixel's variance of that
/// mean from the shards' spread) and caches it.
pub fn merge(
    shards: &[CellResult],
    plan: &ReferencePlan,
    entry: &CacheEntry,
    scene: &Path,
    window: Window,
) -> Result<Reference> {
    let n = shards.len();
    if n < 2 || n != plan.shards as usize {
        bail!("a reference needs its {} shards, got {n}", plan.shards);
    }
    let pixels = shards[0].color.len();
    let mut sum = vec![glam::DVec3::ZERO; pixels];
    let (mut y_sum, mut y_sq) = (vec![0.0f64; pixels], vec![0.0f64; pixels]);
    for shard in shards {
        for (p, c) in shard.color.iter().enumerate() {
            let rgb = Rgb::from_array(*c);
            sum[p] += rgb.as_dvec3();
            let y = luminance(rgb) as f64;
            y_sum[p] += y;
            y_sq[p] += y * y;
        }
    }
    let k = n as f64;
    let mean: Vec<Rgb> = sum.iter().map(|s| (*s / k).as_vec3()).collect();
    // The variance of one shard's pixel, over the k shards averaged.
    let variance: Vec<f64> = y_sum
        .iter()
        .zip(&y_sq)
        .map(|(&s, &q)| ((q - s * s / k) / (k - 1.0)).max(0.0) / k)
        .collect();
    let cpu_time: f64 = shards.iter().map(|s| s.cpu_time).sum();

    let aov = Aov {
        name: VARIANCE_LAYER.into(),
        channels: vec![VARIANCE_CHANNEL.into()],
        preview: false,
    };
    let mut film = Film::new(window.width, window.height, window, vec![aov]);
    film.color.clone_from(&mean);
    film.aov_data = variance.iter().map(|&v| v as f32).collect();
    let metadata: Metadata = vec![
        ("scene".into(), scene.display().to_string()),
        ("key".into(), entry.key.clone()),
        ("integrator".into(), plan.spec.kind.clone()),
        ("samples".into(), plan.total_samples().to_string()),
        ("shards".into(), plan.shards.to_string()),
        ("cpu_time".into(), format!("{cpu_time:.3}")),
    ];
    image_io::write_exr(&film, &entry.file, &metadata)?;
    // As read back from the cache (f32 variances), so that a cached run reports the same.
    let mut reference = Reference::new(
        mean,
        film.aov_data.iter().map(|&v| v as f64).collect(),
        entry.file.clone(),
    );
    reference.samples = Some(plan.total_samples());
    reference.cpu_time = Some(cpu_time);
    Ok(reference)
}

/// The cache key: a hash of the scene's text and of every file it names (meshes, maps,
/// measured BRDFs, plugin libraries), the overrides, the reference's samples and shards, and
/// the executable.
fn key(scene: &Path, overrides: &[String], plan: &ReferencePlan) -> Result<String> {
    let text = std::fs::read_to_string(scene)
        .with_context(|| format!("cannot read `{}`", scene.display()))?;
    let base = scene.parent().unwrap_or(Path::new(""));
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    text.hash(&mut hasher);
    overrides.hash(&mut hasher);
    (plan.total_samples(), plan.shards, &plan.spec.kind).hash(&mut hasher);
    // The baseline's parameters, when it has any beyond the study's (a `path` row's).
    let params: Vec<_> = plan
        .spec
        .params
        .iter()
        .filter(|(k, _)| k.as_str() != lumis_integrators::mis::SAMPLES)
        .collect();
    if !params.is_empty() || plan.camera_samples.is_some() {
        (
            ron::to_string(&params).unwrap_or_default(),
            plan.camera_samples,
        )
            .hash(&mut hasher);
    }
    executable_hash().hash(&mut hasher);
    let mut strings = Vec::new();
    if let Ok(document) = ron::from_str::<ron::Value>(&text) {
        collect_strings(&document, &mut strings);
    }
    strings.extend(overrides.iter().filter_map(|o| {
        o.split_once('=')
            .map(|(_, v)| v.trim_matches('"').to_string())
    }));
    strings.sort();
    strings.dedup();
    for s in strings {
        let path = base.join(&s);
        if path.is_file() {
            let bytes = std::fs::read(&path)
                .with_context(|| format!("cannot read `{}`", path.display()))?;
            (s, bytes).hash(&mut hasher);
        }
    }
    Ok(format!("{:016x}", hasher.finish()))
}

fn collect_strings(value: &ron::Value, out: &mut Vec<String>) {
    match value {
        ron::Value::String(s) => out.push(s.clone()),
        ron::Value::Seq(items) => items.iter().for_each(|v| collect_strings(v, out)),
        ron::Value::Map(map) => map.iter().for_each(|(k, v)| {
            collect_strings(k, out);
            collect_strings(v, out);
        }),
        ron::Value::Option(Some(v)) => collect_strings(v, out),
        _ => {}
    }
}

/// A hash of this program's executable: any change to the code invalidates cached references.
fn executable_hash() -> u64 {
    static HASH: OnceLock<u64> = OnceLock::new();
    *HASH.get_or_init(|| {
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        match std::env::current_exe().and_then(std::fs::read) {
            Ok(bytes) => bytes.hash(&mut hasher),
            // Without the executable, the version at least.
            Err(_) => env!("CARGO_PKG_VERSION").hash(&mut hasher),
        }
        hasher.finish()
    })
}
