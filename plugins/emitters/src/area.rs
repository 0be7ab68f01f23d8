//! `area`: a surface that emits uniform radiance; attached to a shape with `emitter: (...)`.
//!
//! Parameters:
//! - `radiance` (rgb, required, W·m⁻²·sr⁻¹): emitted radiance.
//! - `scale` (float, default 1, dimensionless): multiplies `radiance`.
//! - `two_sided` (bool, default false): emit from both sides, not only the front (the side the
//!   shape's normal points to).
//!
//! Sampling: on triangle meshes, a triangle is chosen in proportion to its area and a point is
//! drawn uniformly on it, the density converted to solid angle; a direction whose ray would not
//! meet that triangle (a point on its edge, up to rounding) is no sample, so that every sample is
//! a direction in which a traced ray finds the light; on a sphere seen from outside,
//! the cone of directions the sphere subtends is sampled uniformly (pbrt-v4 §6.2.4), which is far
//! better than area sampling for small, distant spheres.

use glam::{Vec2, Vec3};
use lumis_core::accel::{Ray, ray_meets_triangle};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::math::warp::square_to_triangle_barycentrics;
use lumis_core::math::{Distribution1D, Frame, Rgb};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use lumis_core::scene::shapes::{ShapeGeometry, Sphere};
use std::f32::consts::{PI, TAU};
use std::sync::Arc;

enum Surface {
    Triangles {
        triangles: Vec<[Vec3; 3]>,
        normals: Vec<Vec3>,
        sizes: Vec<TriangleSize>,
        by_area: Distribution1D,
        area: f32,
    },
    Sphere(Sphere),
}

pub struct AreaEmitter {
    radiance: Rgb,
    two_sided: bool,
    surface: Surface,
}

impl AreaEmitter {
    fn emits_toward(&self, normal: Vec3, wi: Vec3) -> bool {
        self.two_sided || normal.dot(wi) < 0.0
    }

    /// Converts an area density at a point seen along `wi` from `distance` to solid angle.
    fn solid_angle_pdf(pdf_area: f32, distance: f32, normal: Vec3, wi: Vec3) -> f32 {
        let cos = normal.dot(wi).abs();
        let pdf = pdf_area * distance * distance / cos;
        if cos > 0.0 && pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }
}

/// A triangle's size as [`surely_meets`] needs it.
#[derive(Clone, Copy, Debug)]
struct TriangleSize {
    longest_edge: f32,
    /// 1 / the smallest of its heights (infinite for a degenerate triangle).
    inv_min_height: f32,
}

impl TriangleSize {
    fn of(p: &[Vec3; 3]) -> Self {
        let longest_edge = (p[1] - p[0])
            .length()
            .max((p[2] - p[1]).length())
            .max((p[0] - p[2]).length());
        let double_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
        TriangleSize {
            longest_edge,
            inv_min_height: longest_edge / double_area,
        }
    }
}

/// 1024 units of roundoff of f32: the margin of [`surely_meets`] (its test finds rays that miss
/// with 32, none with 48).
const MEETS_TOLERANCE: f32 = 1024.0 * (f32::EPSILON / 2.0);

/// Whether the ray from `origin` toward the point with barycentrics `b` on a triangle of `size`
/// (`to` = the point − `origin`, `cos` = |cos| of the angle at the triangle), traced along the
/// rounded direction, meets it in the watertight test by a margin wide enough to skip the test
/// (a first-order error estimate with a constant set by a test, not a proof): the point lies deeper inside than rounding can move it, and far enough from the
/// origin that the test's distance bound cannot reject it. The bound: the point, the direction
/// and the test's edge functions are each off by a few units of roundoff of the lengths
/// involved (the triangle, the distance, the coordinates of both ends), which in barycentrics
/// is divided by the triangle's smallest height, and by `cos`, since a grazing ray spreads an
/// error over the surface; [`MEETS_TOLERANCE`] times their sum is 21 times the smallest
/// constant with which `points_deemed_surely_met_are_met` finds no miss. `false`
/// leaves the decision to the exact test.
#[inline]
fn surely_meets(b: [f32; 3], to: Vec3, origin: Vec3, cos: f32, size: TriangleSize) -> bool {
    let distance = to.length();
    let lengths = size.longest_edge + distance + origin.length() + (origin + to).length();
    let tolerance = MEETS_TOLERANCE * lengths * size.inv_min_height / cos;
    b[0].min(b[1]).min(b[2]) > tolerance && distance > tolerance * size.longest_edge
}

/// sin²θ of the cone a sphere of radius r subtends from distance d, and 1 − cos θ, computed so
/// that tiny cones do not round to zero.
fn cone(radius: f32, distance2: f32) -> (f32, f32) {
    let sin2_max = radius * radius / distance2;
    let one_minus_cos_max = if sin2_max < 1e-3 {
        // 1 − √(1 − x) = x/2 + x²/8 + ..., exact enough here and free of cancellation.
        sin2_max * 0.5 + sin2_max * sin2_max * 0.125
    } else {
        1.0 - (1.0 - sin2_max).max(0.0).sqrt()
    };
    (sin2_max, one_minus_cos_max)
}

impl Emitter for AreaEmitter {
    fn sample_direction(&self, reference: &ReferencePoint, u: Vec2) -> Option<EmitterSample> {
        let (position, normal, pdf, wi) = match &self.surface {
            Surface::Triangles {
                triangles,
                normals,
                sizes,
                by_area,
                area,
            } => {
                let (i, ux) = by_area.sample_reuse(u.x);
                let (b0, b1) = square_to_triangle_barycentrics(Vec2::new(ux, u.y));
                let [p0, p1, p2] = triangles[i];
                let b2 = 1.0 - b0 - b1;
                let p = b0 * p0 + b1 * p1 + b2 * p2;
                let to = p - reference.position;
                let wi = to.normalize_or_zero();
                // A point within a few ulps of an edge (u at 0 or 1/2) is reached along the
                // rounded direction `wi` only by chance: where the ray misses the triangle, a
                // ray traced along `wi` finds no light (pdf_direction 0) and so must this sample.
                // Points well inside need not be tested.
                let cos = normals[i].dot(wi).abs();
                if !surely_meets([b0, b1, b2], to, reference.position, cos, sizes[i]) {
                    let ray = Ray {
                        origin: reference.position,
                        direction: wi,
                        t_max: f32::INFINITY,
                    };
                    if !ray_meets_triangle(&ray, &triangles[i]) {
                        return None;
                    }
                }
                let pdf = Self::solid_angle_pdf(1.0 / area, to.length(), normals[i], wi);
                (p, normals[i], pdf, wi)
            }
            Surface::Sphere(s) => {
                let to_center = s.center - reference.position;
                let d2 = to_center.length_squared();
                if d2 <= s.radius * s.radius {
                    // Inside the sphere: uniform area sampling.
                    let z = 1.0 - 2.0 * u.x;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let phi = TAU * u.y;
                    let n = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    let p = s.center + s.radius * n;
                    let to = p - reference.position;
                    let distance = to.length();
                    let area = 4.0 * PI * s.radius * s.radius;
                    let wi = to.normalize_or_zero();
                    (p, n, Self::solid_angle_pdf(1.0 / area, distance, n, wi), wi)
                } else {
                    let (sin2_max, one_minus_cos_max) = cone(s.radius, d2);
                    // Uniform in the cone: 1 − cos θ uniform in [0, 1 − cos θmax].
                    let one_minus_cos = u.x * one_minus_cos_max;
                    let sin2 = one_minus_cos * (2.0 - one_minus_cos);
                    let cos = 1.0 - one_minus_cos;
                    // Angle α at the centre between the axis and the point the direction meets.
                    let sin_max = sin2_max.sqrt();
                    let cos_alpha = sin2 / sin_max + cos * (1.0 - sin2 / sin2_max).max(0.0).sqrt();
                    let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
                    let phi = TAU * u.y;
                    let frame = Frame::from_normal(-to_center / d2.sqrt());
                    let n = frame.to_world(Vec3::new(
                        sin_alpha * phi.cos(),
                        sin_alpha * phi.sin(),
                        cos_alpha,
                    ));
                    let p = s.center + s.radius * n;
                    let wi = (p - reference.position).normalize_or_zero();
                    (p, n, 1.0 / (TAU * one_minus_cos_max), wi)
                }
            }
        };
        if !(pdf > 0.0 && pdf.is_finite()) || wi == Vec3::ZERO || !self.emits_toward(normal, wi) {
            return None;
        }
        Some(EmitterSample {
            wi,
            position: Some(position),
            pdf,
            radiance: self.radiance,
        })
    }

    fn pdf_direction(&self, reference: &ReferencePoint, wi: Vec3, hit: Option<&EmitterHit>) -> f32 {
        match (&self.surface, hit) {
            (Surface::Triangles { area, .. }, Some(hit)) => {
                Self::solid_angle_pdf(1.0 / area, hit.distance, hit.normal, wi)
            }
            (Surface::Sphere(s), hit) => {
                let to_center = s.center - reference.position;
                let d2 = to_center.length_squared();
                if d2 > s.radius * s.radius {
                    // Outside: uniform in the cone. Membership is decided by sin θ from the cross
                    // product (accurate for tiny cones), with a margin of a few f32 roundings of a
                    // unit vector so that directions sampled on the silhouette stay inside.
                    let sin_max = s.radius / d2.sqrt() + 2.5e-7;
                    let sin2 = wi.cross(to_center).length_squared() / d2;
                    let in_cone = wi.dot(to_center) > 0.0 && sin2 <= sin_max * sin_max;
                    return if in_cone {
                        1.0 / (TAU * cone(s.radius, d2).1)
                    } else {
                        0.0
                    };
                }
                let area = 4.0 * PI * s.radius * s.radius;
                hit.map_or(0.0, |h| {
                    Self::solid_angle_pdf(1.0 / area, h.distance, h.normal, wi)
                })
            }
            (Surface::Triangles { .. }, None) => 0.0,
        }
    }

    fn eval(&self, wi: Vec3, hit: Option<&EmitterHit>) -> Rgb {
        match hit {
            Some(h) if self.emits_toward(h.normal, wi) => self.radiance,
            _ => Rgb::ZERO,
        }
    }

    fn is_delta(&self) -> bool {
        false
    }
}

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "radiance",
        kind: ParamKind::Rgb {
            default: None,
            max: lumis_core::limits::MAX_EMISSION,
        },
        unit: "W/(m²·sr)",
        description: "emitted radiance",
    },
    crate::SCALE,
    ParamSpec {
        name: "two_sided",
        kind: ParamKind::Bool {
            default: Some(false),
        },
        unit: "",
        description: "emit from both sides of the surface",
    },
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    let radiance = params.rgb("radiance")? * params.float("scale")?;
    let two_sided = params.bool("two_sided")?;
    let surface = match context.shape {
        None => {
            return Err(PluginError::Invalid(
                "an `area` emitter must be attached to a shape (write it as the shape's `emitter`)"
                    .into(),
            ));
        }
        Some(ShapeGeometry::Sphere(s)) => Surface::Sphere(*s),
        Some(ShapeGeometry::Mesh(mesh)) => {
            let triangles: Vec<[Vec3; 3]> =
                (0..mesh.indices.len()).map(|i| mesh.triangle(i)).collect();
            let normals = (0..mesh.indices.len())
                .map(|i| mesh.triangle_normal(i))
                .collect();
            let sizes = triangles.iter().map(TriangleSize::of).collect();
            let areas: Vec<f32> = (0..mesh.indices.len())
                .map(|i| mesh.triangle_area(i))
                .collect();
            let by_area = Distribution1D::new(&areas).ok_or_else(|| {
                PluginError::Invalid("an `area` emitter's shape has no area".into())
            })?;
            let area = by_area.total() as f32;
            Surface::Triangles {
                triangles,
                normals,
                sizes,
                by_area,
                area,
            }
        }
    };
    Ok(Arc::new(AreaEmitter {
        radiance,
        two_sided,
        surface,
    }))
}

inventory::submit! {
    EmitterPlugin {
        name: "area",
        description: "uniform emission from a shape's surface, sampled by area or by subtended cone",
        params: PARAMS,
        create,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lumis_core::sampler::Sampler;

    /// Wherever `surely_meets` skips the watertight test, the test would have found the
    /// triangle: triangles of every shape (slivers of aspect 10⁴ too), near and far from the
    /// origin, seen from distances of 10⁻³ to 10⁴ of their size and at grazing angles down to
    /// 10⁻⁵ rad, at points drawn uniformly and at points within a few ulps to 10⁻³ of an edge or
    /// a vertex. And the skip is no rarity: it covers 9 in 10 points drawn uniformly and seen
    /// from 0.1 to 100 times the triangle's size at elevations above 0.05 rad (95.5 % here).
    #[test]
    fn points_deemed_surely_met_are_met() {
        let mut sampler = Sampler::new(3, 0, 0);
        let (mut ordinary, mut skipped_ordinary, mut skipped_near_edge) = (0u32, 0u32, 0u32);
        let mut triangles: Vec<[Vec3; 3]> = vec![
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1e-4, 0.0),
            ],
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1e-4, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            [
                Vec3::new(1e4, 2e4, -3e4),
                Vec3::new(1e4 + 3.0, 2e4, -3e4),
                Vec3::new(1e4, 2e4 + 2.0, -3e4 + 1.0),
            ],
            [
                Vec3::new(-500.0, 0.0, -500.0),
                Vec3::new(500.0, 0.0, -500.0),
                Vec3::new(0.0, 0.0, 700.0),
            ],
        ];
        // And random ones: anywhere within ±1000, of size 1e-2 to 10, some of them slivers.
        for k in 0..20 {
            let mut point = || {
                let (a, b) = (sampler.next_2d(), sampler.next_2d());
                Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5)
            };
            let (offset, size) = (
                point() * 2000.0,
                10f32.powf(-2.0 + 3.0 * point().x.abs() * 2.0),
            );
            let (a, b) = (offset + point() * size, offset + point() * size);
            // A third vertex near the edge ab (a sliver) or anywhere.
            let squeeze = if k % 2 == 0 { 1e-3 } else { 1.0 };
            let c = (a + b) * 0.5 + point() * size * squeeze;
            triangles.push([a, b, c]);
        }
        for (index, p) in triangles.iter().enumerate() {
            let size = TriangleSize::of(p);
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            for case in 0..40_000 {
                let (u, v, w) = (sampler.next_2d(), sampler.next_2d(), sampler.next_2d());
                // Barycentrics: uniform, or one of them (or two: a vertex) within a few ulps to
                // 1e-3 of zero.
                let (mut b0, mut b1) = square_to_triangle_barycentrics(u);
                let near_edge = case % 3 != 0;
                if near_edge {
                    let tiny = 10f32.powf(-3.0 - 4.0 * w.x) * (w.y - 0.5).signum();
                    match case % 4 {
                        0 => b0 = tiny.abs(),
                        1 => b1 = tiny.abs(),
                        2 => b1 = 1.0 - b0 - tiny.abs(),
                        _ => (b0, b1) = (tiny.abs(), tiny.abs()),
                    }
                }
                let b2 = 1.0 - b0 - b1;
                if b0.min(b1).min(b2) < 0.0 {
                    continue;
                }
                // The origin: at a distance 1e-3 to 1e4 times the triangle's size, at an
                // elevation over its plane down to 1e-5 rad (grazing) or up to 90°.
                let grazing = case % 5 == 0;
                let elevation = if grazing {
                    10f32.powf(-5.0 + 3.0 * v.x)
                } else {
                    0.05 + 1.5 * v.x
                };
                let distance = size.longest_edge * 10f32.powf(-3.0 + 7.0 * v.y);
                let frame = Frame::from_normal(normal);
                let phi = TAU * w.y;
                let local = Vec3::new(
                    elevation.cos() * phi.cos(),
                    elevation.cos() * phi.sin(),
                    elevation.sin() * if case % 2 == 0 { 1.0 } else { -1.0 },
                );
                let point = b0 * p[0] + b1 * p[1] + b2 * p[2];
                let origin = point + distance * frame.to_world(local);
                // As `sample_direction` computes them.
                let to = point - origin;
                let wi = to.normalize_or_zero();
                let cos = normal.dot(wi).abs();
                let sure = surely_meets([b0, b1, b2], to, origin, cos, size);
                // Seen at 0.1 to 100 times its size, neither a sliver nor far from the origin.
                if !near_edge
                    && !grazing
                    && (2.0 / 7.0..5.0 / 7.0).contains(&v.y)
                    && (index == 0 || index == 4)
                {
                    ordinary += 1;
                    skipped_ordinary += sure as u32;
                }
                if sure {
                    skipped_near_edge += (b0.min(b1).min(b2) < 1e-2) as u32;
                    let ray = Ray {
                        origin,
                        direction: wi,
                        t_max: f32::INFINITY,
                    };
                    assert!(
                        ray_meets_triangle(&ray, p),
                        "triangle {p:?}: barycentrics ({b0}, {b1}, {b2}) from {origin} missed"
                    );
                }
            }
        }
        // Points that skip the test close to an edge: where a bound too tight would show.
        assert!(
            skipped_near_edge > 1_000,
            "only {skipped_near_edge} points within 1e-2 of an edge skipped the test"
        );
        assert!(
            skipped_ordinary as f64 > 0.9 * ordinary as f64,
            "{skipped_ordinary} of {ordinary} ordinary points skipped the test"
        );
    }
}
