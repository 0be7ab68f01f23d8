//! `envmap`: an environment map, radiance arriving from infinitely far away in every direction.
//!
//! Parameters:
//! - `file` (path, required): an equirectangular (latitude–longitude) RGB OpenEXR image.
//! - `scale` (float, default 1): multiplies the radiance.
//! - `rotation` (float, default 0, degrees): turns the map about the y (up) axis.
//!
//! Mapping: the top row is straight up (+y), the bottom row straight down; the image's centre
//! column looks toward −z, its left edge toward +z and its first quarter toward −x: a direction
//! d = (sin θ sin φ, cos θ, −sin θ cos φ) has u = (φ + π) / 2π, v = θ / π. Each pixel is a cell
//! of constant radiance: `eval` reads the pixel a direction falls in, and sampling picks pixels
//! from a 2D piecewise-constant distribution proportional to luminance × sin θ, so `pdf` is the
//! density of exactly that choice: p(u, v) / (2π² sin θ).
//!
//! Pixels that are not valid radiance — negative (lossy compression leaves small negative
//! values) or not finite — are read as zero in that channel.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::image_io::read_exr_rgb;
use lumis_core::math::{Distribution2D, Rgb, luminance};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use std::f32::consts::{PI, TAU};
use std::sync::Arc;

pub struct EnvironmentMap {
    width: usize,
    height: usize,
    pixels: Vec<Rgb>,
    /// Over (u, v); `None` for a black map, which then is never sampled.
    distribution: Option<Distribution2D>,
    /// Rotation about +y, as (cos, sin).
    rotation: (f32, f32),
}

impl EnvironmentMap {
    /// Builds the map from linear RGB pixels (row-major, top row first), replacing values that
    /// are not valid radiance by zero.
    pub fn new(
        width: usize,
        height: usize,
        mut pixels: Vec<Rgb>,
        scale: f32,
        rotation_degrees: f32,
    ) -> Self {
        for p in &mut pixels {
            *p = Rgb::from(p.to_array().map(|c| {
                if c.is_finite() && c > 0.0 {
                    c * scale
                } else {
                    0.0
                }
            }));
        }
        let weights: Vec<f32> = (0..height)
            .flat_map(|y| {
                let sin_theta = (PI * (y as f32 + 0.5) / height as f32).sin();
                let pixels = &pixels;
                (0..width).map(move |x| luminance(pixels[y * width + x]) * sin_theta)
            })
            .collect();
        let distribution = Distribution2D::new(&weights, width, height);
        let (sin, cos) = rotation_degrees.to_radians().sin_cos();
        EnvironmentMap {
            width,
            height,
            pixels,
            distribution,
            rotation: (cos, sin),
        }
    }

    /// World direction to map coordinates (u, v) in [0, 1]², and sin θ.
    fn to_uv(&self, d: Vec3) -> (Vec2, f32) {
        let (c, s) = self.rotation;
        // Undo the rotation about +y.
        let local = Vec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z);
        let cos_theta = local.y.clamp(-1.0, 1.0);
        let phi = local.x.atan2(-local.z);
        let u = ((phi + PI) / TAU).clamp(0.0, 1.0);
        let v = (cos_theta.acos() / PI).clamp(0.0, 1.0);
        (
            Vec2::new(u, v),
            (1.0 - cos_theta * cos_theta).max(0.0).sqrt(),
        )
    }

    /// Map coordinates to a world direction, and sin θ.
    fn to_direction(&self, uv: Vec2) -> (Vec3, f32) {
        let phi = uv.x * TAU - PI;
        let theta = uv.y * PI;
        let (sin_theta, cos_theta) = theta.sin_cos();
        let local = Vec3::new(sin_theta * phi.sin(), cos_theta, -sin_theta * phi.cos());
        let (c, s) = self.rotation;
        (
            Vec3::new(
                c * local.x + s * local.z,
                local.y,
                -s * local.x + c * local.z,
            ),
            sin_theta,
        )
    }

    /// Solid-angle density of the direction at map coordinates `uv`.
    fn pdf_at(distribution: &Distribution2D, uv: Vec2, sin_theta: f32) -> f32 {
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let pdf = distribution.pdf(uv) / (2.0 * PI * PI * sin_theta);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    fn lookup(&self, uv: Vec2) -> Rgb {
        let x = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        self.pixels[y * self.width + x]
    }
}

impl Emitter for EnvironmentMap {
    fn sample_direction(&self, _: &ReferencePoint, u: Vec2) -> Option<EmitterSample> {
        let distribution = self.distribution.as_ref()?;
        let (uv, _) = distribution.sample(u);
        let (wi, _) = self.to_direction(uv);
        // Radiance and density are those of the direction as `eval` and `pdf_direction` see it
        // (on a pixel's edge, rounding can move it into the neighbour), from one conversion.
        let (uv, sin_theta) = self.to_uv(wi);
        let pdf = Self::pdf_at(distribution, uv, sin_theta);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(EmitterSample {
            wi,
            position: None,
            pdf,
            radiance: self.lookup(uv),
        })
    }

    fn pdf_direction(&self, _: &ReferencePoint, wi: Vec3, _: Option<&EmitterHit>) -> f32 {
        let Some(d) = &self.distribution else {
            return 0.0;
        };
        let (uv, sin_theta) = self.to_uv(wi);
        Self::pdf_at(d, uv, sin_theta)
    }

    fn eval(&self, wi: Vec3, _: Option<&EmitterHit>) -> Rgb {
        self.lookup(self.to_uv(wi).0)
    }

    fn is_delta(&self) -> bool {
        false
    }

    fn is_environment(&self) -> bool {
        true
    }
}

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "file",
        kind: ParamKind::Path,
        unit: "",
        description: "equirectangular RGB OpenEXR image, relative to the scene file",
    },
    crate::SCALE,
    ParamSpec {
        name: "rotation",
        kind: ParamKind::Float {
            default: Some(0.0),
            min: -360.0,
            max: 360.0,
        },
        unit: "degrees",
        description: "rotation of the map about the up (y) axis",
    },
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    crate::not_on_a_shape(context, "envmap")?;
    let path = params.path("file")?;
    let scale = params.float("scale")?;
    let rotation = params.float("rotation")?;
    let image = read_exr_rgb(&path)
        .map_err(|e| PluginError::Invalid(format!("{}: {e}", params.plugin())))?;
    if image.width == 0 || image.height == 0 {
        return Err(PluginError::Invalid(format!(
            "{}: `{}` is empty",
            params.plugin(),
            path.display()
        )));
    }
    Ok(Arc::new(EnvironmentMap::new(
        image.width,
        image.height,
        image.pixels,
        scale,
        rotation,
    )))
}

inventory::submit! {
    EmitterPlugin {
        name: "envmap",
        description: "equirectangular environment map, importance sampled by luminance × sin θ",
        params: PARAMS,
        create,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(rotation: f32) -> EnvironmentMap {
        EnvironmentMap::new(8, 4, vec![Rgb::ONE; 32], 1.0, rotation)
    }

    #[test]
    fn directions_and_map_coordinates_round_trip_at_poles_and_seam() {
        for rotation in [0.0, 30.0, -135.0] {
            let m = map(rotation);
            for uv in [
                Vec2::new(0.5, 0.5),
                Vec2::new(1e-6, 0.3),
                Vec2::new(1.0 - 1e-6, 0.7),
                Vec2::new(0.25, 1e-5),
                Vec2::new(0.75, 1.0 - 1e-5),
            ] {
                let (d, _) = m.to_direction(uv);
                assert!((d.length() - 1.0).abs() < 1e-5);
                let (back, _) = m.to_uv(d);
                // At the poles u is undefined; elsewhere u wraps at the seam.
                let du = (back.x - uv.x).abs();
                let pole = uv.y < 1e-4 || uv.y > 1.0 - 1e-4;
                assert!(
                    pole || du.min(1.0 - du) < 1e-4,
                    "rotation {rotation}: {uv} -> {d} -> {back}"
                );
                assert!(
                    (back.y - uv.y).abs() < 1e-3,
                    "rotation {rotation}: {uv} -> {back}"
                );
            }
        }
    }

    #[test]
    fn mapping_follows_the_documented_convention() {
        let m = map(0.0);
        assert!(
            m.to_direction(Vec2::new(0.5, 0.5))
                .0
                .abs_diff_eq(-Vec3::Z, 1e-6)
        );
        assert!(
            m.to_direction(Vec2::new(0.0, 0.5))
                .0
                .abs_diff_eq(Vec3::Z, 1e-6)
        );
        assert!(
            m.to_direction(Vec2::new(0.25, 0.5))
                .0
                .abs_diff_eq(-Vec3::X, 1e-6)
        );
        assert!(
            m.to_direction(Vec2::new(0.3, 0.0))
                .0
                .abs_diff_eq(Vec3::Y, 1e-6)
        );
        // Rotating by 90 degrees about +y carries the centre (-z) to -x.
        let r = map(90.0);
        assert!(
            r.to_direction(Vec2::new(0.5, 0.5))
                .0
                .abs_diff_eq(-Vec3::X, 1e-6)
        );
    }
}
