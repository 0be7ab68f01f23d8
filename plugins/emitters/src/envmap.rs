//! `envmap`: an environment map, radiance arriving from infinitely far away in every direction.
//!
//! Parameters:
//! - `file` (path, required): an equirectangular (latitude–longitude) RGB OpenEXR image.
//! - `scale` (float, default 1): multiplies the radiance.
//! - `rotation` (float, default 0, degrees): turns the map about `rotation_axis`.
//! - `rotation_axis` (vector, default (0, 1, 0)): the axis `rotation` turns the map about,
//!   right-handed; any rotation of the map is one angle about one axis (`lumis import` writes
//!   a Mitsuba env map's `to_world` so).
//! - `interpolation` (choice, default `nearest`, or `bilinear`): how radiance varies between
//!   pixels (below).
//! - `orientation` (choice, default `lumis`, or `mitsuba`): which way the map faces (below).
//! - `compensation` (bool, default false): MIS compensation (below).
//!
//! Mapping (`orientation: "lumis"`): the top row is straight up (+y), the bottom row straight
//! down; the image's centre column looks toward −z, its left edge toward +z and its first quarter
//! toward −x: a direction d = (sin θ sin φ, cos θ, −sin θ cos φ) has u = (φ + π) / 2π, v = θ / π.
//! `orientation: "mitsuba"` turns the map by 180° about y, as Mitsuba 3 places it (centre column
//! toward +z, first quarter toward +x): the same as adding 180 to `rotation`.
//!
//! `interpolation: "nearest"`: each pixel is a cell of constant radiance, pixel (i, j) spanning
//! u ∈ [i, i + 1]/W and θ ∈ π·[j, j + 1]/H. Sampling picks cells from a 2D piecewise-constant
//! distribution proportional to luminance × sin θ (at the row's centre), so `pdf` is the density
//! of exactly that choice: p(u, v) / (2π² sin θ).
//!
//! `interpolation: "bilinear"` (Mitsuba 3's placement): pixel (i, j) is a sample at
//! u = (i + ½)/W (wrapping around at the seam) and θ = π·j/(H − 1), so the first and last rows
//! sit on the poles, and radiance is interpolated bilinearly between the four surrounding
//! samples. Sampling is a piecewise-bilinear warp: the weights w = luminance × sin θ at the
//! samples, interpolated bilinearly, are the density in (u, v); a patch between four samples is
//! chosen by its integral (the mean of its corners), then a point inside it by inverting the
//! bilinear density's marginal and conditional (both linear) in closed form. `pdf` is that
//! density exactly, w(u, v) / ∫w / (2π² sin θ), the same as Mitsuba's `envmap` samples with.
//! The map must then be at least 2 pixels high.
//!
//! `compensation: true` (Karlík, Šik, Vévoda, Skřivánek and Křivánek, "MIS compensation:
//! optimizing sampling techniques in multiple importance sampling", SIGGRAPH Asia 2019; as
//! pbrt-v4's `ImageInfiniteLight`): the map is sampled from max(Y − Ȳ, Ȳ/100) instead of its
//! luminance Y, Ȳ the mean luminance over the sphere (solid-angle weighted). Where the map is
//! below its mean, BSDF sampling, combined with light sampling by MIS, already does well; taking
//! those directions away from light sampling spends its samples on the bright parts. The floor
//! (ours; pbrt-v4 uses 0) keeps every direction with radiance reachable by light sampling, so
//! that light sampling alone (`light`) stays unbiased. A constant map is then sampled uniformly.
//! Meant for MIS with BSDF sampling; off by default.
//!
//! Pixels that are not valid radiance — negative (lossy compression leaves small negative
//! values) or not finite — are read as zero in that channel.
//!
//! Why one file of over 600 lines: one plugin, one file: loading and checking the image, the
//! piecewise-constant and bilinear sampling and their lane forms; with its tests.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::image_io::read_exr_rgb;
use lumis_core::math::lanes::{LaneKernel, Lanes, V3, by_groups, with_widest_lanes};
use lumis_core::math::{Distribution2D, Rgb, luminance, prefetch};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use std::f32::consts::{FRAC_PI_2, PI, TAU};
use std::sync::Arc;

/// How radiance varies between the pixels of the map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// One constant radiance per pixel.
    Nearest,
    /// Bilinear between samples at the pixels' centres in u and on the poles' rows in θ.
    Bilinear,
}

/// Which way the map faces (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Orientation {
    /// Centre column toward −z.
    Lumis,
    /// Centre column toward +z, as Mitsuba 3.
    Mitsuba,
}

/// How a map is placed and read.
#[derive(Clone, Copy, Debug)]
pub struct MapSettings {
    pub scale: f32,
    /// About `rotation_axis`, in degrees.
    pub rotation_degrees: f32,
    /// The axis of the rotation, (0, 1, 0) by default; need not be of unit length.
    pub rotation_axis: Vec3,
    pub interpolation: Interpolation,
    pub orientation: Orientation,
    /// Sample from max(Y − Ȳ, Ȳ/100) instead of Y (MIS compensation).
    pub compensation: bool,
}

impl Default for MapSettings {
    fn default() -> Self {
        MapSettings {
            scale: 1.0,
            rotation_degrees: 0.0,
            rotation_axis: Vec3::Y,
            interpolation: Interpolation::Nearest,
            orientation: Orientation::Lumis,
            compensation: false,
        }
    }
}

pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Row-major, top row first.
    texels: Vec<Texel>,
    sampling: Sampling,
    /// Rotation about +y (with the orientation's half turn), as (cos, sin).
    rotation: (f32, f32),
    /// The map's frame when turned about another axis than +y: the columns are where the
    /// map's own axes go (world = frame · map), the orientation's half turn included. `None`:
    /// `rotation` alone, the arithmetic of a turn about +y.
    frame: Option<[Vec3; 3]>,
}

/// A pixel's radiance, and beside it the number `pdf` reads at the same pixel: a direction's
/// `eval` and `pdf_direction` (and a light sample's radiance and density) read one cache line of
/// a map that is far larger than the caches, not one in each of two tables.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Texel {
    radiance: Rgb,
    /// Nearest: the density over (u, v) of the pixel's cell. Bilinear: the sampling weight at
    /// the pixel's sample (luminance × sin θ). Zero for a black map.
    density: f32,
}

/// The tables that sampling reads; `None` for a black map, which then is never sampled.
enum Sampling {
    /// Over (u, v), one cell per pixel.
    Nearest(Option<Distribution2D>),
    Bilinear(Option<BilinearWarp>),
}

/// The piecewise-bilinear density over the W × (H − 1) patches between pixel samples, whose
/// corner weights are the texels' `density`.
struct BilinearWarp {
    /// Patches by their integrals: patch (i, j) has corners (i, j), (i + 1 mod W, j),
    /// (i, j + 1), (i + 1 mod W, j + 1).
    patches: Distribution2D,
    /// ∫ over [0, 1]² of the interpolated weights.
    integral: f32,
}

/// Where a point of the map falls between pixel samples (bilinear placement).
struct Corners {
    /// Indices of the samples (i0, j0), (i1, j0), (i0, j1), (i1, j1).
    index: [usize; 4],
    /// Position between them, in [0, 1]².
    fx: f32,
    fy: f32,
}

impl Corners {
    fn lerp<T>(&self, value: impl Fn(usize) -> T) -> T
    where
        T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let [a, b, c, d] = self.index.map(value);
        let (fx, fy) = (self.fx, self.fy);
        (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
    }
}

/// Inverts the CDF of the density on [0, 1] proportional to (1 − x)·a + x·b (a, b ≥ 0, not
/// both 0), in the form that keeps its precision when a ≈ b.
fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    if u <= 0.0 {
        return 0.0;
    }
    let x = u * (a + b) / (a + ((1.0 - u) * a * a + u * b * b).sqrt());
    x.clamp(0.0, 1.0 - f32::EPSILON / 2.0)
}

impl EnvironmentMap {
    /// Builds a nearest-interpolated map in lumis' orientation from linear RGB pixels
    /// (row-major, top row first), replacing values that are not valid radiance by zero.
    pub fn new(
        width: usize,
        height: usize,
        pixels: Vec<Rgb>,
        scale: f32,
        rotation_degrees: f32,
    ) -> Self {
        let settings = MapSettings {
            scale,
            rotation_degrees,
            ..MapSettings::default()
        };
        Self::with_settings(width, height, pixels, &settings)
            .expect("a nearest-interpolated map of any size is valid")
    }

    /// Builds a map with any settings; fails for a bilinear map less than 2 pixels high, or
    /// pixels that do not fill width × height.
    pub fn with_settings(
        width: usize,
        height: usize,
        mut pixels: Vec<Rgb>,
        settings: &MapSettings,
    ) -> Result<Self, String> {
        if width == 0 || height == 0 || pixels.len() != width * height {
            return Err(format!(
                "{} pixels do not make a {width}x{height} map",
                pixels.len()
            ));
        }
        for p in &mut pixels {
            *p = Rgb::from(p.to_array().map(|c| {
                if c.is_finite() && c > 0.0 {
                    c * settings.scale
                } else {
                    0.0
                }
            }));
        }
        // sin θ of each row, where the sampling weights are taken.
        let row_sin: Vec<f32> = match settings.interpolation {
            Interpolation::Nearest => (0..height)
                .map(|y| (PI * (y as f32 + 0.5) / height as f32).sin())
                .collect(),
            Interpolation::Bilinear => (0..height)
                .map(|y| (PI * y as f32 / (height - 1).max(1) as f32).sin().max(0.0))
                .collect(),
        };
        let mut sampled: Vec<f32> = pixels.iter().map(|&p| luminance(p)).collect();
        if settings.compensation {
            compensate(&mut sampled, &row_sin, width);
        }
        // luminance × sin θ at each pixel (nearest: its cell; bilinear: its sample).
        let weights: Vec<f32> = (0..height)
            .flat_map(|y| {
                let sampled = &sampled;
                let sin_theta = row_sin[y];
                (0..width).map(move |x| sampled[y * width + x] * sin_theta)
            })
            .collect();
        let (sampling, densities) = match settings.interpolation {
            Interpolation::Nearest => {
                let distribution = Distribution2D::new(&weights, width, height);
                let densities = match &distribution {
                    Some(d) => (0..height)
                        .flat_map(|y| (0..width).map(move |x| d.cell_pdf(x, y)))
                        .collect(),
                    None => vec![0.0; width * height],
                };
                (Sampling::Nearest(distribution), densities)
            }
            Interpolation::Bilinear => {
                if height < 2 {
                    return Err(format!(
                        "bilinear interpolation needs a map at least 2 pixels high (its first \
                         and last rows sit on the poles); this one is {width}x{height}"
                    ));
                }
                (
                    Sampling::Bilinear(BilinearWarp::new(&weights, width)),
                    weights,
                )
            }
        };
        let mut texels = lumis_core::huge_pages::vec_with_capacity(pixels.len());
        texels.extend(
            pixels
                .into_iter()
                .zip(densities)
                .map(|(radiance, density)| Texel { radiance, density }),
        );
        let (sin, cos) = settings.rotation_degrees.to_radians().sin_cos();
        // Mitsuba's orientation is a half turn more: exactly (−cos, −sin).
        let rotation = match settings.orientation {
            Orientation::Lumis => (cos, sin),
            Orientation::Mitsuba => (-cos, -sin),
        };
        let axis = settings.rotation_axis.as_dvec3();
        if !(axis.is_finite() && axis.length_squared() > 0.0) {
            return Err(format!(
                "`rotation_axis` must be a finite non-zero vector, found {}",
                settings.rotation_axis
            ));
        }
        let frame = (axis.x != 0.0 || axis.z != 0.0).then(|| {
            let turn = glam::DMat3::from_axis_angle(
                axis.normalize(),
                (settings.rotation_degrees as f64).to_radians(),
            );
            let half = match settings.orientation {
                Orientation::Lumis => glam::DMat3::IDENTITY,
                Orientation::Mitsuba => glam::DMat3::from_rotation_y(std::f64::consts::PI),
            };
            let m = turn * half;
            [m.x_axis, m.y_axis, m.z_axis].map(|c| c.as_vec3())
        });
        // A turn about −y is one about +y the other way.
        let rotation = if axis.y < 0.0 && frame.is_none() {
            (rotation.0, -rotation.1)
        } else {
            rotation
        };
        Ok(EnvironmentMap {
            width,
            height,
            texels,
            sampling,
            rotation,
            frame,
        })
    }

    /// Whether the map is turned about another axis than +y (through its general frame; a turn
    /// about +y has arithmetic of its own).
    pub fn has_general_frame(&self) -> bool {
        self.frame.is_some()
    }

    /// World direction to map coordinates (u, v) in [0, 1]², and sin θ.
    #[inline]
    pub fn to_uv(&self, d: Vec3) -> (Vec2, f32) {
        let (u, v, sin_theta) = self.to_uv_lanes::<f32>(V3::splat(d));
        (Vec2::new(u, v), sin_theta)
    }

    /// [`Self::to_uv`] of each lane's direction: u, v and sin θ.
    #[inline(always)]
    fn to_uv_lanes<L: Lanes>(&self, d: V3<L>) -> (L, L, L) {
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let (x, y, z) = match &self.frame {
            // Undo the rotation about +y.
            None => {
                let (c, s) = (L::splat(self.rotation.0), L::splat(self.rotation.1));
                (c * d.x - s * d.z, d.y, s * d.x + c * d.z)
            }
            // The map's coordinates: the frame's transpose (its inverse) times d.
            Some(frame) => {
                let [x, y, z] = frame.map(|axis| V3::splat(axis).dot(d));
                (x, y, z)
            }
        };
        let cos_theta = y.clamp(-one, one);
        let phi = x.atan2(-z);
        let u = ((phi + L::splat(PI)) / L::splat(TAU)).clamp(zero, one);
        let v = (cos_theta.acos() / L::splat(PI)).clamp(zero, one);
        (u, v, (one - cos_theta * cos_theta).max(zero).sqrt())
    }

    /// [`Self::to_uv`]'s coordinates within 3e-5 (1/16 of a pixel of a 2048 × 1024
    /// map), at a fraction of the cost of `atan2` and `acos`: good enough to prefetch the
    /// texel `eval` will read, not to replace it.
    #[inline]
    pub fn approximate_uv(&self, d: Vec3) -> Vec2 {
        let (x, y, z) = match &self.frame {
            None => {
                let (c, s) = self.rotation;
                (c * d.x - s * d.z, d.y, -(s * d.x + c * d.z))
            }
            Some([a, b, c]) => (a.dot(d), b.dot(d), -c.dot(d)),
        };
        let u = (approximate_atan2(x, z) + PI) / TAU;
        let v = approximate_acos(y.clamp(-1.0, 1.0)) / PI;
        Vec2::new(u.clamp(0.0, 1.0), v.clamp(0.0, 1.0))
    }

    /// Map coordinates to a world direction.
    #[inline]
    pub fn to_direction(&self, uv: Vec2) -> Vec3 {
        self.to_direction_lanes::<f32>(uv.x, uv.y).lane(0)
    }

    /// [`Self::to_direction`] of each lane's coordinates (u, v).
    #[inline(always)]
    fn to_direction_lanes<L: Lanes>(&self, u: L, v: L) -> V3<L> {
        let phi = u * L::splat(TAU) - L::splat(PI);
        let theta = v * L::splat(PI);
        let (sin_theta, cos_theta) = theta.sin_cos();
        let (sin_phi, cos_phi) = phi.sin_cos();
        let (x, z) = (sin_theta * sin_phi, -sin_theta * cos_phi);
        match &self.frame {
            None => {
                let (c, s) = (L::splat(self.rotation.0), L::splat(self.rotation.1));
                V3::new(c * x + s * z, cos_theta, -s * x + c * z)
            }
            Some([a, b, c]) => V3::splat(*a) * x + V3::splat(*b) * cos_theta + V3::splat(*c) * z,
        }
    }

    /// Solid-angle density of the direction at map coordinates `uv`.
    #[inline]
    fn pdf_at(&self, uv: Vec2, sin_theta: f32) -> f32 {
        let pdf_uv = match &self.sampling {
            Sampling::Nearest(Some(_)) => self.texels[self.nearest_index(uv)].density,
            Sampling::Bilinear(Some(warp)) => self.bilinear_pdf_uv(warp, uv),
            Sampling::Nearest(None) | Sampling::Bilinear(None) => return 0.0,
        };
        solid_angle_pdf(pdf_uv, sin_theta)
    }

    /// Radiance and solid-angle density at map coordinates `uv`, from one read of the texels.
    #[inline]
    fn radiance_and_pdf(&self, uv: Vec2, sin_theta: f32) -> (Rgb, f32) {
        match &self.sampling {
            Sampling::Nearest(Some(_)) => {
                let texel = self.texels[self.nearest_index(uv)];
                (texel.radiance, solid_angle_pdf(texel.density, sin_theta))
            }
            Sampling::Bilinear(Some(warp)) => self.bilinear_radiance_and_pdf(warp, uv, sin_theta),
            Sampling::Nearest(None) | Sampling::Bilinear(None) => (self.lookup(uv), 0.0),
        }
    }

    /// The pixel whose cell contains map coordinates `uv` (nearest placement).
    #[inline]
    fn nearest_index(&self, uv: Vec2) -> usize {
        // Through u32, whose conversion is shorter than usize's on x86-64 (the same value:
        // uv is in [0, 1], and a side in u32).
        let x = ((uv.x * self.width as f32) as u32 as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as u32 as usize).min(self.height - 1);
        y * self.width + x
    }

    /// The four pixel samples around map coordinates `uv` (bilinear placement).
    #[inline]
    fn corners(&self, uv: Vec2) -> Corners {
        let (w, h) = (self.width, self.height);
        // Sample i sits at x = i; the seam wraps x in [−½, 0) to the last column.
        let mut x = uv.x * w as f32 - 0.5;
        if x < 0.0 {
            x += w as f32;
        }
        let i0 = (x as usize).min(w - 1);
        let i1 = if i0 + 1 == w { 0 } else { i0 + 1 };
        let y = uv.y * (h - 1) as f32;
        let j0 = (y as usize).min(h - 2);
        Corners {
            index: [
                j0 * w + i0,
                j0 * w + i1,
                (j0 + 1) * w + i0,
                (j0 + 1) * w + i1,
            ],
            fx: (x - i0 as f32).clamp(0.0, 1.0),
            fy: (y - j0 as f32).clamp(0.0, 1.0),
        }
    }

    #[inline]
    fn lookup(&self, uv: Vec2) -> Rgb {
        match self.sampling {
            Sampling::Nearest(_) => self.texels[self.nearest_index(uv)].radiance,
            Sampling::Bilinear(_) => self.bilinear_lookup(uv),
        }
    }

    /// Map coordinates of a sample drawn with `u`, or `None` for a black map.
    #[inline]
    fn sample_uv(&self, u: Vec2) -> Option<Vec2> {
        match &self.sampling {
            Sampling::Nearest(d) => Some(d.as_ref()?.sample(u)),
            Sampling::Bilinear(warp) => Some(self.bilinear_sample_uv(warp.as_ref()?, u)),
        }
    }

    // The bilinear paths stay out of line, so that the nearest ones keep their size.

    #[inline(never)]
    fn bilinear_pdf_uv(&self, warp: &BilinearWarp, uv: Vec2) -> f32 {
        self.corners(uv).lerp(|i| self.texels[i].density) / warp.integral
    }

    #[inline(never)]
    fn bilinear_lookup(&self, uv: Vec2) -> Rgb {
        self.corners(uv).lerp(|i| self.texels[i].radiance)
    }

    #[inline(never)]
    fn bilinear_radiance_and_pdf(
        &self,
        warp: &BilinearWarp,
        uv: Vec2,
        sin_theta: f32,
    ) -> (Rgb, f32) {
        let corners = self.corners(uv);
        let pdf_uv = corners.lerp(|i| self.texels[i].density) / warp.integral;
        (
            corners.lerp(|i| self.texels[i].radiance),
            solid_angle_pdf(pdf_uv, sin_theta),
        )
    }

    #[inline(never)]
    fn bilinear_sample_uv(&self, warp: &BilinearWarp, u: Vec2) -> Vec2 {
        let (col, row, within) = warp.patches.sample_cell(u);
        let (w, h) = (self.width, self.height);
        let col1 = if col + 1 == w { 0 } else { col + 1 };
        let weight = |i: usize, j: usize| self.texels[j * w + i].density;
        let (w00, w10) = (weight(col, row), weight(col1, row));
        let (w01, w11) = (weight(col, row + 1), weight(col1, row + 1));
        // The marginal in y is linear, then the conditional in x given y.
        let fy = sample_linear(within.y, w00 + w10, w01 + w11);
        let fx = sample_linear(
            within.x,
            w00 * (1.0 - fy) + w01 * fy,
            w10 * (1.0 - fy) + w11 * fy,
        );
        let mut x = (col as f32 + fx + 0.5) / w as f32;
        if x >= 1.0 {
            x -= 1.0;
        }
        Vec2::new(x, (row as f32 + fy) / (h - 1) as f32)
    }
}

/// Solid-angle density of a direction with density `pdf_uv` over (u, v) and polar sine
/// `sin_theta` (zero at the poles, where the map's parametrisation degenerates).
#[inline]
fn solid_angle_pdf(pdf_uv: f32, sin_theta: f32) -> f32 {
    if sin_theta <= 0.0 {
        return 0.0;
    }
    let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
    if pdf.is_finite() { pdf.max(0.0) } else { 0.0 }
}

/// Replaces the luminances `sampled` (rows of `width`, row `y` at sin θ = `row_sin[y]`) by
/// max(Y − Ȳ, Ȳ/100), Ȳ their solid-angle-weighted mean; a black map stays black.
fn compensate(sampled: &mut [f32], row_sin: &[f32], width: usize) {
    let (mut sum, mut area) = (0.0f64, 0.0f64);
    for (row, &sin_theta) in sampled.chunks(width).zip(row_sin) {
        sum += sin_theta as f64 * row.iter().map(|&y| y as f64).sum::<f64>();
        area += sin_theta as f64 * width as f64;
    }
    if !(sum > 0.0 && area > 0.0) {
        return;
    }
    let mean = (sum / area) as f32;
    for y in sampled.iter_mut() {
        *y = (*y - mean).max(0.01 * mean);
    }
}

impl BilinearWarp {
    /// From the weights at the pixels' samples (luminance × sin θ, rows of `width`).
    fn new(weights: &[f32], width: usize) -> Option<Self> {
        let height = weights.len() / width;
        let patch_weights: Vec<f32> = (0..height - 1)
            .flat_map(|j| {
                let weights = &weights;
                (0..width).map(move |i| {
                    let i1 = (i + 1) % width;
                    let row = |j: usize| weights[j * width + i] + weights[j * width + i1];
                    0.25 * (row(j) + row(j + 1))
                })
            })
            .collect();
        let integral =
            patch_weights.iter().map(|&w| w as f64).sum::<f64>() / patch_weights.len() as f64;
        let patches = Distribution2D::new(&patch_weights, width, height - 1)?;
        Some(BilinearWarp {
            patches,
            integral: integral as f32,
        })
    }
}

impl EnvironmentMap {
    /// Nearest: the texel of the pixel `sampled` lies in, read now, so that its cache miss (a
    /// map is larger than the caches) overlaps the trigonometry that follows.
    #[inline(always)]
    fn read_early(&self, sampled: Vec2) -> Option<(usize, Texel)> {
        match self.sampling {
            Sampling::Nearest(_) => {
                let index = self.nearest_index(sampled);
                Some((index, std::hint::black_box(self.texels[index])))
            }
            Sampling::Bilinear(_) => None,
        }
    }

    /// The sample along `wi`, whose map coordinates are `uv` and polar sine `sin_theta`, with the
    /// texel read early (`early`), or none where its density is not positive.
    #[inline(always)]
    fn finish_sample(
        &self,
        early: Option<(usize, Texel)>,
        wi: Vec3,
        uv: Vec2,
        sin_theta: f32,
    ) -> Option<EmitterSample> {
        // Radiance and density are those of the direction as `eval` and `pdf_direction` see it
        // (on a pixel's edge, rounding can move it into the neighbour), from one conversion.
        let (radiance, pdf) = match early {
            Some((index, texel)) if index == self.nearest_index(uv) => {
                (texel.radiance, solid_angle_pdf(texel.density, sin_theta))
            }
            _ => self.radiance_and_pdf(uv, sin_theta),
        };
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(EmitterSample {
            wi,
            position: None,
            pdf,
            radiance,
        })
    }
}

/// The kernel of [`EnvironmentMap`]'s `eval_pdf_batch`.
struct EvalPdfBatch<'a> {
    map: &'a EnvironmentMap,
    wi: &'a [Vec3],
    out: &'a mut [(Rgb, f32)],
}

impl LaneKernel for EvalPdfBatch<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes, const W: usize>(self) {
        let EvalPdfBatch { map, wi, out } = self;
        by_groups::<W, _>(
            out,
            #[inline(always)]
            |indices, out| {
                let (u, v, sin_theta) = map.to_uv_lanes(V3::<L>::from_fn(|i| wi[indices[i]]));
                for (k, out) in out.iter_mut().enumerate() {
                    let uv = Vec2::new(u.lane(k), v.lane(k));
                    *out = (map.lookup(uv), map.pdf_at(uv, sin_theta.lane(k)));
                }
            },
        );
    }
}

/// The kernel of [`EnvironmentMap`]'s `sample_direction_batch`.
struct SampleBatch<'a> {
    map: &'a EnvironmentMap,
    u: &'a [Vec2],
    out: &'a mut [Option<EmitterSample>],
}

impl LaneKernel for SampleBatch<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lanes, const W: usize>(self) {
        let SampleBatch { map, u, out } = self;
        by_groups::<W, _>(
            out,
            #[inline(always)]
            |indices, out| {
                let mut sampled = [Vec2::ZERO; W];
                let mut early = [None; W];
                for (i, &index) in indices.iter().enumerate() {
                    // Only a black map draws nothing, and then in no lane.
                    let Some(s) = map.sample_uv(u[index]) else {
                        out.fill(None);
                        return;
                    };
                    sampled[i] = s;
                    early[i] = map.read_early(s);
                }
                let wi = map
                    .to_direction_lanes(L::from_fn(|i| sampled[i].x), L::from_fn(|i| sampled[i].y));
                let (u, v, sin_theta) = map.to_uv_lanes(wi);
                for (k, out) in out.iter_mut().enumerate() {
                    let uv = Vec2::new(u.lane(k), v.lane(k));
                    *out = map.finish_sample(early[k], wi.lane(k), uv, sin_theta.lane(k));
                }
            },
        );
    }
}

impl Emitter for EnvironmentMap {
    fn sample_direction(&self, _: &ReferencePoint, u: Vec2) -> Option<EmitterSample> {
        let sampled = self.sample_uv(u)?;
        let early = self.read_early(sampled);
        let wi = self.to_direction(sampled);
        let (uv, sin_theta) = self.to_uv(wi);
        self.finish_sample(early, wi, uv, sin_theta)
    }

    /// Four or eight samples at a time ([`with_widest_lanes`]): the tables are read lane by
    /// lane, the trigonometry of the conversions to and from directions runs in the lanes, with
    /// the same operations as `sample_direction`'s.
    fn sample_direction_batch(
        &self,
        _: &[ReferencePoint],
        u: &[Vec2],
        out: &mut [Option<EmitterSample>],
    ) {
        with_widest_lanes(SampleBatch { map: self, u, out });
    }

    fn pdf_direction(&self, _: &ReferencePoint, wi: Vec3, _: Option<&EmitterHit>) -> f32 {
        let (uv, sin_theta) = self.to_uv(wi);
        self.pdf_at(uv, sin_theta)
    }

    fn eval(&self, wi: Vec3, _: Option<&EmitterHit>) -> Rgb {
        self.lookup(self.to_uv(wi).0)
    }

    fn eval_pdf(&self, _: &ReferencePoint, wi: Vec3, _: Option<&EmitterHit>) -> (Rgb, f32) {
        let (uv, sin_theta) = self.to_uv(wi);
        (self.lookup(uv), self.pdf_at(uv, sin_theta))
    }

    /// Four or eight directions at a time ([`with_widest_lanes`]): their conversions to map
    /// coordinates run in the lanes, with `eval_pdf`'s operations; the texels are read lane by
    /// lane.
    fn eval_pdf_batch(&self, _: &[ReferencePoint], wi: &[Vec3], out: &mut [(Rgb, f32)]) {
        assert!(wi.len() == out.len(), "one result per direction");
        with_widest_lanes(EvalPdfBatch { map: self, wi, out });
    }

    fn prefetch_sample(&self, u: &dyn Fn() -> Vec2) {
        if let Sampling::Nearest(Some(d)) = &self.sampling {
            prefetch(&self.texels[d.prefetch_sample(u())]);
        }
    }

    fn prefetch(&self, wi: Vec3) {
        if let Sampling::Nearest(_) = self.sampling {
            prefetch(&self.texels[self.nearest_index(self.approximate_uv(wi))]);
        }
    }

    fn is_delta(&self) -> bool {
        false
    }

    fn is_environment(&self) -> bool {
        true
    }
}

/// atan2(y, x) within 1.2e-5 rad: a degree-9 odd polynomial for atan on [0, 1] (fitted for
/// the least largest error), then the octant.
#[inline]
fn approximate_atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ay > ax { (ax, ay) } else { (ay, ax) };
    let a = if large > 0.0 { small / large } else { 0.0 };
    let s = a * a;
    let mut r = a
        * (0.999_866_3
            + s * (-0.330_304_86 + s * (0.180_159_6 + s * (-0.085_156_81 + s * 0.020_845_34))));
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 { -r } else { r }
}

/// acos(x) for x in [−1, 1] within 7e-5 rad (Abramowitz and Stegun 4.4.45).
#[inline]
fn approximate_acos(x: f32) -> f32 {
    let a = x.abs();
    let r =
        (1.0 - a).sqrt() * (((-0.018_729_3 * a + 0.074_261_0) * a - 0.212_114_4) * a + 1.570_728_8);
    if x < 0.0 { PI - r } else { r }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "envmap";
pub const FILE: &str = "file";
pub const ROTATION: &str = "rotation";
pub const ROTATION_AXIS: &str = "rotation_axis";
pub const INTERPOLATION: &str = "interpolation";
pub const ORIENTATION: &str = "orientation";
pub const COMPENSATION: &str = "compensation";
/// Values of its choices.
pub const NEAREST: &str = "nearest";
pub const BILINEAR: &str = "bilinear";
pub const LUMIS: &str = "lumis";
pub const MITSUBA: &str = "mitsuba";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: FILE,
        kind: ParamKind::Path,
        unit: "",
        description: "equirectangular RGB OpenEXR image, relative to the scene file",
    },
    crate::SCALE,
    ParamSpec {
        name: ROTATION,
        kind: ParamKind::Float {
            default: Some(0.0),
            min: -360.0,
            max: 360.0,
        },
        unit: "degrees",
        description: "rotation of the map about `rotation_axis`",
    },
    ParamSpec {
        name: ROTATION_AXIS,
        kind: ParamKind::Vec3 {
            default: Some([0.0, 1.0, 0.0]),
        },
        unit: "",
        description: "the axis `rotation` turns the map about (right-handed; not zero)",
    },
    ParamSpec {
        name: INTERPOLATION,
        kind: ParamKind::Choice {
            options: &[NEAREST, BILINEAR],
            default: NEAREST,
        },
        unit: "",
        description: "nearest: constant radiance per pixel; bilinear: between samples at pixel centres in u and on the poles' rows in θ (Mitsuba 3's placement), sampled by a piecewise-bilinear warp",
    },
    ParamSpec {
        name: ORIENTATION,
        kind: ParamKind::Choice {
            options: &[LUMIS, MITSUBA],
            default: LUMIS,
        },
        unit: "",
        description: "lumis: the map's centre column looks toward −z; mitsuba: toward +z, as Mitsuba 3 (a half turn about y)",
    },
    ParamSpec {
        name: COMPENSATION,
        kind: ParamKind::Bool {
            default: Some(false),
        },
        unit: "",
        description: "MIS compensation (Karlík et al. 2019): sample from max(Y − mean Y, mean Y / 100) instead of the luminance Y, for MIS with BSDF sampling",
    },
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    crate::not_on_a_shape(context, NAME)?;
    let path = params.path(FILE)?;
    let settings = MapSettings {
        scale: params.float(crate::SCALE.name)?,
        rotation_degrees: params.float(ROTATION)?,
        rotation_axis: params.vec3(ROTATION_AXIS)?,
        interpolation: match params.choice(INTERPOLATION)? {
            BILINEAR => Interpolation::Bilinear,
            _ => Interpolation::Nearest,
        },
        orientation: match params.choice(ORIENTATION)? {
            MITSUBA => Orientation::Mitsuba,
            _ => Orientation::Lumis,
        },
        compensation: params.bool(COMPENSATION)?,
    };
    let image = read_exr_rgb(&path)
        .map_err(|e| PluginError::Invalid(format!("{}: {e}", params.plugin())))?;
    if image.width == 0 || image.height == 0 {
        return Err(PluginError::Invalid(format!(
            "{}: `{}` is empty",
            params.plugin(),
            path.display()
        )));
    }
    let map = EnvironmentMap::with_settings(image.width, image.height, image.pixels, &settings)
        .map_err(|e| {
            PluginError::Invalid(format!("{}: `{}`: {e}", params.plugin(), path.display()))
        })?;
    Ok(Arc::new(map))
}

inventory::submit! {
    EmitterPlugin {
        name: NAME,
        description: "equirectangular environment map (nearest or bilinear), importance sampled by luminance × sin θ",
        params: PARAMS,
        create,
    }
}
