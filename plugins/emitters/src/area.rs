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
use lumis_core::emitter::{
    Emitter, EmitterContext, EmitterHit, EmitterLanes, EmitterSample, EmitterSampleLanes,
    ReferencePoint, sample_direction_in_lanes,
};
use lumis_core::geometry::{Ray, ShapeGeometry, Sphere, ray_meets_triangle};
use lumis_core::math::frame::FrameLanes;
use lumis_core::math::lanes::{Lanes, MAX_WIDTH, Mask, V3};
use lumis_core::math::warp::square_to_triangle_barycentrics_lanes;
use lumis_core::math::{Distribution1D, Rgb};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
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
    /// The shape cannot block a shadow ray toward its samples: a sphere (sampled in the cone
    /// it subtends from outside, anywhere from inside: either way the segment to the sample
    /// crosses no other part of it), or a planar mesh.
    never_blocks_samples: bool,
}

impl AreaEmitter {
    /// Whether the surface emits toward `wi` from a point of normal `normal`.
    #[inline(always)]
    fn emits_toward<L: Lanes>(&self, normal: V3<L>, wi: V3<L>) -> L::Mask {
        normal.dot(wi).lt(L::splat(0.0)) | L::Mask::from_fn(|_| self.two_sided)
    }
}

/// Converts an area density at a point seen along `wi` from `distance` to solid angle; 0
/// where it is not finite.
#[inline(always)]
fn solid_angle_pdf<L: Lanes>(pdf_area: f32, distance: L, normal: V3<L>, wi: V3<L>) -> L {
    let cos = normal.dot(wi).abs();
    let pdf = L::splat(pdf_area) * distance * distance / cos;
    L::select(cos.gt(L::splat(0.0)) & pdf.is_finite(), pdf, L::splat(0.0))
}

/// A triangle's size as [`surely_meets`] needs it.
#[derive(Clone, Copy, Debug)]
pub struct TriangleSize {
    /// The length of its longest edge.
    pub longest_edge: f32,
    /// 1 / the smallest of its heights (infinite for a degenerate triangle).
    pub inv_min_height: f32,
}

impl TriangleSize {
    /// The size of the triangle of vertices `p`.
    pub fn of(p: &[Vec3; 3]) -> Self {
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
#[inline(always)]
pub fn surely_meets<L: Lanes>(
    b: [L; 3],
    to: V3<L>,
    origin: V3<L>,
    cos: L,
    (longest_edge, inv_min_height): (L, L),
) -> L::Mask {
    let distance = to.length();
    let lengths = longest_edge + distance + origin.length() + (origin + to).length();
    let tolerance = L::splat(MEETS_TOLERANCE) * lengths * inv_min_height / cos;
    b[0].min(b[1]).min(b[2]).gt(tolerance) & distance.gt(tolerance * longest_edge)
}

/// sin²θ of the cone a sphere of radius r subtends from distance d, and 1 − cos θ, computed so
/// that tiny cones do not round to zero.
#[inline(always)]
fn cone<L: Lanes>(radius: f32, distance2: L) -> (L, L) {
    let sin2_max = L::splat(radius * radius) / distance2;
    // 1 − √(1 − x) = x/2 + x²/8 + ..., exact enough for small x and free of cancellation.
    let series = sin2_max * L::splat(0.5) + sin2_max * sin2_max * L::splat(0.125);
    let direct = L::splat(1.0) - (L::splat(1.0) - sin2_max).max(L::splat(0.0)).sqrt();
    (
        sin2_max,
        L::select(sin2_max.lt(L::splat(1e-3)), series, direct),
    )
}

/// A point, its normal, its solid-angle density and its direction from `reference`, in each
/// lane.
type SphereSample<L> = (V3<L>, V3<L>, L, V3<L>);

/// From inside sphere `s`: uniform in area, at height 1 − 2 u0 and at the angle whose sine and
/// cosine are `phi`. Functions rather than closures, which would be compiled apart from the
/// AVX2 kernel that calls them.
#[inline(always)]
fn sphere_area_sample<L: Lanes>(
    s: &Sphere,
    reference: V3<L>,
    u0: L,
    (sin_phi, cos_phi): (L, L),
) -> SphereSample<L> {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let z = one - L::splat(2.0) * u0;
    let r = (one - z * z).max(zero).sqrt();
    let n = V3::new(r * cos_phi, r * sin_phi, z);
    let p = V3::splat(s.center) + n * L::splat(s.radius);
    let to = p - reference;
    let wi = to.normalize_or_zero();
    let area = 4.0 * PI * s.radius * s.radius;
    (p, n, solid_angle_pdf(1.0 / area, to.length(), n, wi), wi)
}

/// From outside sphere `s`: uniform in the cone it subtends, 1 − cos θ = u0 (1 − cos θmax);
/// `to_center` is the centre less `reference`, `d2` its squared length.
#[inline(always)]
fn sphere_cone_sample<L: Lanes>(
    s: &Sphere,
    reference: V3<L>,
    (to_center, d2): (V3<L>, L),
    u0: L,
    (sin_phi, cos_phi): (L, L),
) -> SphereSample<L> {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let (sin2_max, one_minus_cos_max) = cone(s.radius, d2);
    let one_minus_cos = u0 * one_minus_cos_max;
    let sin2 = one_minus_cos * (L::splat(2.0) - one_minus_cos);
    let cos = one - one_minus_cos;
    // Angle α at the centre between the axis and the point the direction meets.
    let sin_max = sin2_max.sqrt();
    let cos_alpha = sin2 / sin_max + cos * (one - sin2 / sin2_max).max(zero).sqrt();
    let sin_alpha = (one - cos_alpha * cos_alpha).max(zero).sqrt();
    let frame = FrameLanes::from_normal(-to_center / d2.sqrt());
    let n = frame.to_world(V3::new(sin_alpha * cos_phi, sin_alpha * sin_phi, cos_alpha));
    let p = V3::splat(s.center) + n * L::splat(s.radius);
    let wi = (p - reference).normalize_or_zero();
    let pdf = one / (L::splat(TAU) * one_minus_cos_max);
    (p, n, pdf, wi)
}

impl EmitterLanes for AreaEmitter {
    /// `sample_direction` in each lane, from the reference points `reference`: the one formula
    /// of the scalar and the batch methods.
    #[inline(always)]
    fn sample_lanes<L: Lanes>(&self, reference: V3<L>, (u0, u1): (L, L)) -> EmitterSampleLanes<L> {
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let (position, normal, pdf, wi, met) = match &self.surface {
            Surface::Triangles {
                triangles,
                normals,
                sizes,
                by_area,
                area,
            } => {
                let mut picked = [(0, 0.0); MAX_WIDTH];
                for (i, picked) in picked.iter_mut().enumerate().take(L::WIDTH) {
                    *picked = by_area.sample_reuse(u0.lane(i));
                }
                let (b0, b1) =
                    square_to_triangle_barycentrics_lanes(L::from_fn(|i| picked[i].1), u1);
                let b2 = one - b0 - b1;
                let vertex = |k: usize| V3::from_fn(|i| triangles[picked[i].0][k]);
                let p = vertex(0) * b0 + vertex(1) * b1 + vertex(2) * b2;
                let to = p - reference;
                let wi = to.normalize_or_zero();
                let normal = V3::from_fn(|i| normals[picked[i].0]);
                // A point within a few ulps of an edge (u at 0 or 1/2) is reached along the
                // rounded direction `wi` only by chance: where the ray misses the triangle, a
                // ray traced along `wi` finds no light (pdf_direction 0) and so must this sample.
                // Points well inside need not be tested.
                let cos = normal.dot(wi).abs();
                let size = (
                    L::from_fn(|i| sizes[picked[i].0].longest_edge),
                    L::from_fn(|i| sizes[picked[i].0].inv_min_height),
                );
                let sure = surely_meets([b0, b1, b2], to, reference, cos, size);
                let met = if sure.all() {
                    sure
                } else {
                    L::Mask::from_fn(|i| {
                        sure.lane(i) || {
                            let ray = Ray {
                                origin: reference.lane(i),
                                direction: wi.lane(i),
                                t_max: f32::INFINITY,
                            };
                            ray_meets_triangle(&ray, &triangles[picked[i].0])
                        }
                    })
                };
                let pdf = solid_angle_pdf(1.0 / area, to.length(), normal, wi);
                (p, normal, pdf, wi, met)
            }
            Surface::Sphere(s) => {
                let to_center = V3::splat(s.center) - reference;
                let d2 = to_center.length_squared();
                let inside = d2.le(L::splat(s.radius * s.radius));
                let phi = (L::splat(TAU) * u1).sin_cos();
                let (p, n, pdf, wi) = if !inside.any() {
                    sphere_cone_sample(s, reference, (to_center, d2), u0, phi)
                } else if inside.all() {
                    sphere_area_sample(s, reference, u0, phi)
                } else {
                    let a = sphere_area_sample(s, reference, u0, phi);
                    let b = sphere_cone_sample(s, reference, (to_center, d2), u0, phi);
                    (
                        V3::select(inside, a.0, b.0),
                        V3::select(inside, a.1, b.1),
                        L::select(inside, a.2, b.2),
                        V3::select(inside, a.3, b.3),
                    )
                };
                (p, n, pdf, wi, L::Mask::from_fn(|_| true))
            }
        };
        let valid =
            met & pdf.gt(zero) & pdf.is_finite() & !wi.is_zero() & self.emits_toward(normal, wi);
        EmitterSampleLanes {
            valid,
            wi,
            position,
            pdf,
        }
    }
}

impl Emitter for AreaEmitter {
    fn sample_direction(&self, reference: &ReferencePoint, u: Vec2) -> Option<EmitterSample> {
        self.sample_lanes::<f32>(V3::splat(reference.position), (u.x, u.y))
            .lane(0, self.radiance)
    }

    fn sample_direction_batch(
        &self,
        reference: &[ReferencePoint],
        u: &[Vec2],
        out: &mut [Option<EmitterSample>],
    ) {
        sample_direction_in_lanes(self, reference, u, out, self.radiance);
    }

    fn pdf_direction(&self, reference: &ReferencePoint, wi: Vec3, hit: Option<&EmitterHit>) -> f32 {
        match (&self.surface, hit) {
            (Surface::Triangles { area, .. }, Some(hit)) => solid_angle_pdf::<f32>(
                1.0 / area,
                hit.distance,
                V3::splat(hit.normal),
                V3::splat(wi),
            ),
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
                        1.0 / (TAU * cone::<f32>(s.radius, d2).1)
                    } else {
                        0.0
                    };
                }
                let area = 4.0 * PI * s.radius * s.radius;
                hit.map_or(0.0, |h| {
                    solid_angle_pdf::<f32>(
                        1.0 / area,
                        h.distance,
                        V3::splat(h.normal),
                        V3::splat(wi),
                    )
                })
            }
            (Surface::Triangles { .. }, None) => 0.0,
        }
    }

    fn eval(&self, wi: Vec3, hit: Option<&EmitterHit>) -> Rgb {
        match hit {
            Some(h) if self.emits_toward::<f32>(V3::splat(h.normal), V3::splat(wi)) => {
                self.radiance
            }
            _ => Rgb::ZERO,
        }
    }

    fn is_delta(&self) -> bool {
        false
    }

    fn own_shape_never_blocks_samples(&self) -> bool {
        self.never_blocks_samples
    }
}

/// Whether all of the triangles' vertices lie on one plane, up to the rounding of their
/// coordinates (4 ulps of the largest): a segment from off the plane to a point on it crosses
/// no other triangle then, except by rounding.
fn is_planar(triangles: &[[Vec3; 3]]) -> bool {
    let largest = triangles.iter().max_by(|a, b| {
        let area = |t: &[Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length_squared();
        area(a).total_cmp(&area(b))
    });
    let Some(&[a, b, c]) = largest else {
        return false;
    };
    let [a, b, c] = [a, b, c].map(Vec3::as_dvec3);
    let normal = (b - a).cross(c - a).normalize_or_zero();
    let vertices = || triangles.iter().flatten();
    let largest_coordinate = vertices().fold(0.0f32, |m, v| m.max(v.abs().max_element()));
    let tolerance = 4.0 * f64::from(f32::EPSILON) * f64::from(largest_coordinate);
    normal != glam::DVec3::ZERO
        && vertices().all(|v| normal.dot(v.as_dvec3() - a).abs() <= tolerance)
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "area";
pub const RADIANCE: &str = "radiance";
pub const TWO_SIDED: &str = "two_sided";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: RADIANCE,
        kind: ParamKind::Rgb {
            default: None,
            max: lumis_core::limits::MAX_EMISSION,
        },
        unit: "W/(m²·sr)",
        description: "emitted radiance",
    },
    crate::SCALE,
    ParamSpec {
        name: TWO_SIDED,
        kind: ParamKind::Bool {
            default: Some(false),
        },
        unit: "",
        description: "emit from both sides of the surface",
    },
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    let radiance = params.rgb(RADIANCE)? * params.float(crate::SCALE.name)?;
    let two_sided = params.bool(TWO_SIDED)?;
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
    let never_blocks_samples = match &surface {
        Surface::Sphere(_) => true,
        Surface::Triangles { triangles, .. } => is_planar(triangles),
    };
    Ok(Arc::new(AreaEmitter {
        radiance,
        two_sided,
        surface,
        never_blocks_samples,
    }))
}

inventory::submit! {
    EmitterPlugin {
        name: NAME,
        description: "uniform emission from a shape's surface, sampled by area or by subtended cone",
        params: PARAMS,
        create,
    }
}
