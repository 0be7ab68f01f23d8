//! `<sensor>` with its `<film>` and `<sampler>`: the scene's camera, film and sampler.

use super::Converter;
use super::properties::{Value, line};
use glam::{DMat4, DVec3};
use lumis_core::scene::description::{
    CameraDescription, CropDescription, FilmDescription, SamplerDescription,
};
use roxmltree::Node;

/// Mitsuba's defaults: an `hdrfilm` of 768×576, an `independent` sampler of 4 samples.
pub(super) const DEFAULT_WIDTH: u32 = 768;
pub(super) const DEFAULT_HEIGHT: u32 = 576;
pub(super) const DEFAULT_SPP: u32 = 4;

impl Converter {
    /// A `perspective` sensor: the camera (and the film, and the sampler).
    pub(super) fn sensor(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        let at = p.line;
        if p.kind != "perspective" {
            self.problem(
                at,
                format!("sensor `{}` is not converted (perspective only)", p.kind),
            );
            return Ok(());
        }
        let mut film = FilmDescription {
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
            output: None,
            crop: None,
            exposure: 0.0,
        };
        let mut film_seen = false;
        for object in p.objects.clone() {
            match object.tag_name().name() {
                "film" => {
                    film_seen = true;
                    film = self.film(&object)?;
                }
                "sampler" => self.sampler(&object)?,
                other => self.problem(
                    line(&object),
                    format!("<{other}> inside the sensor is not converted"),
                ),
            }
        }
        if !film_seen {
            self.note(at, "no <film>: Mitsuba's default 768x576 hdrfilm");
        }
        let matrix = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        let position = matrix.transform_point3(DVec3::ZERO);
        let forward = matrix.transform_vector3(DVec3::Z);
        let up = matrix.transform_vector3(DVec3::Y);
        let (f, u) = (forward.normalize_or_zero(), up.normalize_or_zero());
        if matrix.determinant() <= 0.0 || f.dot(u).abs() > 1e-4 || f == DVec3::ZERO {
            self.problem(
                at,
                "the sensor's `to_world` mirrors or skews the view, which lumis' camera cannot",
            );
            return Ok(());
        }
        let axis = p.string("fov_axis")?.map_or("x".to_string(), |(s, _)| s);
        let Some((fov, _)) = p.number("fov")? else {
            self.problem(
                at,
                "a sensor without `fov` (a focal length) is not converted",
            );
            return Ok(());
        };
        let vertical = vertical_fov(fov, &axis, film.width, film.height)
            .ok_or_else(|| format!("line {at}: unknown fov_axis `{axis}`"))?;
        for clip in ["near_clip", "far_clip"] {
            if let Some((_, l)) = p.take(clip) {
                self.note(l, format!("`{clip}` is ignored: lumis does not clip"));
            }
        }
        let f32s = |v: DVec3| v.as_vec3().to_array();
        self.camera = Some(CameraDescription {
            position: Some(f32s(position)),
            target: Some(f32s(position + f)),
            up: Some(f32s(u)),
            fov: Some(vertical as f32),
            gltf: None,
            name: None,
        });
        self.film = Some(film);
        self.finish(p, "the sensor");
        Ok(())
    }

    /// An `hdrfilm`: size and crop window.
    fn film(&mut self, node: &Node) -> Result<FilmDescription, String> {
        let mut p = self.properties(node)?;
        let at = p.line;
        if p.kind != "hdrfilm" {
            self.problem(
                at,
                format!("film `{}` is not converted (hdrfilm only)", p.kind),
            );
        }
        let mut int = |name: &str, default: i64| -> Result<Option<i64>, String> {
            match p.take(name) {
                Some((Value::Int(n), _)) if (0..=65536).contains(&n) => Ok(Some(n)),
                Some((_, l)) => Err(format!(
                    "line {l}: `{name}` must be an integer in 0..=65536"
                )),
                None => Ok((default >= 0).then_some(default)),
            }
        };
        let width = int("width", DEFAULT_WIDTH.into())?.unwrap_or(DEFAULT_WIDTH.into()) as u32;
        let height = int("height", DEFAULT_HEIGHT.into())?.unwrap_or(DEFAULT_HEIGHT.into()) as u32;
        let crop = match (
            int("crop_offset_x", 0)?,
            int("crop_offset_y", 0)?,
            int("crop_width", -1)?,
            int("crop_height", -1)?,
        ) {
            (Some(x), Some(y), cw, ch) if cw.is_some() || ch.is_some() || x > 0 || y > 0 => {
                Some(CropDescription {
                    x: x as u32,
                    y: y as u32,
                    width: cw.unwrap_or(width as i64 - x) as u32,
                    height: ch.unwrap_or(height as i64 - y) as u32,
                })
            }
            _ => None,
        };
        // Output formats do not change the image.
        for ignored in ["pixel_format", "component_format", "file_format", "banner"] {
            p.ignore(ignored);
        }
        let mut box_filter = false;
        for object in p.objects.clone() {
            match object.tag_name().name() {
                "rfilter" => {
                    let kind = self.xml.attribute(&object, "type")?.unwrap_or_default();
                    if kind != "box" {
                        self.problem(
                            line(&object),
                            format!("reconstruction filter `{kind}` is not converted (box only)"),
                        );
                    }
                    box_filter = true;
                }
                other => self.problem(
                    line(&object),
                    format!("<{other}> inside the film is not converted"),
                ),
            }
        }
        if !box_filter {
            self.note(
                at,
                "no <rfilter>: Mitsuba filters with a Gaussian by default, lumis with a box over \
                 the pixel (the same mean image, blurred differently)",
            );
        }
        if let Some((_, l)) = p.take("sample_border") {
            self.note(
                l,
                "`sample_border` is ignored (lumis' box filter stays in its pixel)",
            );
        }
        self.finish(p, "the film");
        Ok(FilmDescription {
            width,
            height,
            output: None,
            crop,
            exposure: 0.0,
        })
    }

    /// An `independent` sampler: samples per pixel and seed.
    fn sampler(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        if p.kind != "independent" {
            self.problem(
                p.line,
                format!("sampler `{}` is not converted (independent only)", p.kind),
            );
            return Ok(());
        }
        let spp = match p.take("sample_count") {
            Some((Value::Int(n), l)) if n > 0 => u32::try_from(n).map_err(|_| {
                format!(
                    "line {l}: `sample_count` {n} is more than lumis takes ({})",
                    u32::MAX
                )
            })?,
            Some((_, l)) => {
                return Err(format!(
                    "line {l}: `sample_count` must be a positive integer"
                ));
            }
            None => DEFAULT_SPP,
        };
        let seed = match p.take("seed") {
            Some((Value::Int(n), _)) if n >= 0 => n,
            Some((_, l)) => return Err(format!("line {l}: `seed` must be a non-negative integer")),
            None => 0,
        };
        self.sampler = Some(SamplerDescription {
            spp,
            seed: seed as u64,
            jitter: true,
        });
        self.finish(p, "the sampler");
        Ok(())
    }
}

/// The vertical field of view, in degrees, of Mitsuba's `fov` along `axis` on a film of
/// `width`×`height`; `None` for an unknown axis.
fn vertical_fov(fov: f64, axis: &str, width: u32, height: u32) -> Option<f64> {
    let (w, h) = (width as f64, height as f64);
    let half = (fov.to_radians() / 2.0).tan();
    let vertical_half = match axis {
        "y" => half,
        "x" => half * h / w,
        "diagonal" => half * h / (w * w + h * h).sqrt(),
        "smaller" if w <= h => half * h / w,
        "smaller" => half,
        "larger" if w >= h => half * h / w,
        "larger" => half,
        _ => return None,
    };
    Some(2.0 * vertical_half.atan().to_degrees())
}
