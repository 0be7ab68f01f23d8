//! `<sensor>` with its `<film>` and `<sampler>`: the scene's camera, film and sampler.

use super::Converter;
use super::properties::{Value, line};
use glam::{DMat4, DVec3};
use lumis_core::scene::description::{
    CameraDescription, CropDescription, FilmDescription, FilterDescription, SamplerDescription,
};
use roxmltree::Node;

/// Mitsuba's defaults: an `hdrfilm` of 768×576, an `independent` sampler of 4 samples.
pub(super) const DEFAULT_WIDTH: u32 = 768;
pub(super) const DEFAULT_HEIGHT: u32 = 576;
pub(super) const DEFAULT_SPP: u32 = 4;

/// Mitsuba's filter when a film names none: its Gaussian, σ = 0.5 pixel.
pub(super) fn default_filter() -> FilterDescription {
    FilterDescription {
        kind: "gaussian".into(),
        radius: None,
        stddev: Some(0.5),
    }
}

/// The 35 mm film's diagonal, in mm, with which Mitsuba turns a focal length into a diagonal
/// field of view.
const FILM_35MM_DIAGONAL: f64 = 43.266_615_305_567_87;

impl Converter {
    /// A `perspective` sensor: the camera (and the film, and the sampler). A sensor that cannot
    /// be converted leaves the scene without a camera, which no `--partial` writes.
    pub(super) fn sensor(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        let at = p.line;
        if p.kind != "perspective" {
            let kind = p.kind.clone();
            self.refuse(
                &mut p,
                format!("sensor `{kind}` is not converted (perspective only)"),
            );
            return Ok(());
        }
        let mut film = FilmDescription {
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
            output: None,
            crop: None,
            exposure: 0.0,
            filter: default_filter(),
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
            self.note(
                at,
                "no <film>: Mitsuba's default 768x576 hdrfilm, with its Gaussian filter",
            );
        }
        let matrix = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        let position = matrix.transform_point3(DVec3::ZERO);
        let forward = matrix.transform_vector3(DVec3::Z);
        let up = matrix.transform_vector3(DVec3::Y);
        let (f, u) = (forward.normalize_or_zero(), up.normalize_or_zero());
        if matrix.determinant() <= 0.0 || f.dot(u).abs() > 1e-4 || f == DVec3::ZERO {
            self.refuse(
                &mut p,
                "the sensor's `to_world` mirrors or skews the view, which lumis' camera cannot",
            );
            return Ok(());
        }
        let focal_length = p.take("focal_length");
        let (fov, axis) = match (p.number("fov")?, focal_length) {
            (Some(_), Some((_, l))) => {
                return Err(format!(
                    "line {l}: a sensor takes `fov` or `focal_length`, not both (as in Mitsuba)"
                ));
            }
            (Some((fov, _)), None) => {
                let axis = p
                    .string("fov_axis")?
                    .map_or("x".to_string(), |(s, _)| s.to_ascii_lowercase());
                (fov, axis)
            }
            (None, focal) => {
                let given = focal.is_some();
                let (text, l) = match focal {
                    Some((Value::Str(s), l)) => (s, l),
                    Some((Value::Float(x), l)) => (x.to_string(), l),
                    Some((Value::Int(n), l)) => (n.to_string(), l),
                    Some((_, l)) => {
                        return Err(format!("line {l}: `focal_length` must be a string"));
                    }
                    None => ("50mm".to_string(), at),
                };
                let mm = text
                    .trim()
                    .strip_suffix("mm")
                    .unwrap_or(text.trim())
                    .trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| *x > 0.0 && x.is_finite())
                    .ok_or_else(|| {
                        format!("line {l}: focal length `{text}` is not a positive number of mm")
                    })?;
                let diagonal = 2.0 * (FILM_35MM_DIAGONAL / (2.0 * mm)).atan().to_degrees();
                if !given {
                    self.note(
                        at,
                        "no `fov`: Mitsuba's default focal length, 50 mm (35 mm film), a \
                         diagonal field of view of 46.8°",
                    );
                }
                (diagonal, "diagonal".to_string())
            }
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(format!(
                "line {at}: the field of view must be in (0, 180) degrees, found {fov}"
            ));
        }
        let vertical = vertical_fov(fov, &axis, film.width, film.height)
            .ok_or_else(|| format!("line {at}: unknown fov_axis `{axis}`"))?;
        for clip in ["near_clip", "far_clip"] {
            if let Some((_, l)) = p.take(clip) {
                self.note(l, format!("`{clip}` is ignored: lumis does not clip"));
            }
        }
        if let Some((_, l)) = p.take("focus_distance") {
            self.note(
                l,
                "`focus_distance` is ignored: a `perspective` sensor is a pinhole, sharp at \
                 every distance (as in Mitsuba)",
            );
        }
        for shutter in ["shutter_open", "shutter_close"] {
            if let Some((_, l)) = p.take(shutter) {
                self.note(
                    l,
                    format!("`{shutter}` is ignored: nothing in the scene moves"),
                );
            }
        }
        for offset in ["principal_point_offset_x", "principal_point_offset_y"] {
            if let Some((x, l)) = p.number(offset)?
                && x != 0.0
            {
                self.problem(l, format!("`{offset}` other than 0 is not converted"));
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

    /// An `hdrfilm` (or a Mitsuba 0.x `ldrfilm`): size, crop window and filter.
    fn film(&mut self, node: &Node) -> Result<FilmDescription, String> {
        let mut p = self.properties(node)?;
        let at = p.line;
        let mut exposure = 0.0;
        match p.kind.as_str() {
            "hdrfilm" => {}
            "ldrfilm" if self.version().is_legacy() => {
                self.note(
                    at,
                    "Mitsuba 0.x `ldrfilm`: lumis renders the same radiance to an OpenEXR \
                     image and a PNG preview; the tone mapping is not applied",
                );
                if let Some((stops, _)) = p.number("exposure")? {
                    exposure = stops as f32;
                }
                for ignored in ["tonemap_method", "gamma", "key", "burn"] {
                    p.ignore(ignored);
                }
            }
            other => {
                self.problem(
                    at,
                    format!("film `{other}` is not converted (hdrfilm only; its size is kept)"),
                );
            }
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
        for ignored in [
            "pixel_format",
            "component_format",
            "file_format",
            "banner",
            "attach_log",
        ] {
            p.ignore(ignored);
        }
        let mut filter = None;
        for object in p.objects.clone() {
            match object.tag_name().name() {
                "rfilter" => filter = Some(self.rfilter(&object)?),
                other => self.problem(
                    line(&object),
                    format!("<{other}> inside the film is not converted"),
                ),
            }
        }
        let filter = match filter {
            Some(f) => f.unwrap_or_else(default_filter),
            None => {
                self.note(
                    at,
                    "no <rfilter>: Mitsuba's default, a Gaussian of σ = 0.5 pixel (lumis \
                     samples it)",
                );
                default_filter()
            }
        };
        // Mitsuba 0.x's name for `sample_border`, which Mitsuba 3 neither upgrades nor knows (it
        // refuses the file as an unreferenced property).
        if let Some((true, l)) = p.boolean("high_quality_edges")? {
            self.note(
                l,
                "`highQualityEdges` (Mitsuba 0.x's `sample_border`; Mitsuba 3 refuses it) is \
                 ignored: lumis cuts the filter at the film's edge and renormalises it (pixels \
                 at the edge differ from Mitsuba 0.x's)",
            );
        }
        if let Some((true, l)) = p.boolean("sample_border")? {
            self.note(
                l,
                "`sample_border` is ignored: lumis cuts the filter at the film's edge and \
                 renormalises it, as Mitsuba does without `sample_border` (pixels at the edge \
                 differ)",
            );
        }
        self.finish(p, "the film");
        Ok(FilmDescription {
            width,
            height,
            output: None,
            crop,
            exposure,
            filter,
        })
    }

    /// An `<rfilter>`: `box`, `tent` (`radius`) or `gaussian` (`stddev`), as lumis' filter of
    /// the same name; `None` after a problem.
    fn rfilter(&mut self, node: &Node) -> Result<Option<FilterDescription>, String> {
        let mut p = self.properties(node)?;
        let mut filter = FilterDescription {
            kind: p.kind.clone(),
            radius: None,
            stddev: None,
        };
        match p.kind.as_str() {
            "box" => {}
            "tent" => filter.radius = p.number("radius")?.map(|(r, _)| r as f32),
            "gaussian" => filter.stddev = p.number("stddev")?.map(|(s, _)| s as f32),
            other => {
                let other = other.to_string();
                self.refuse(
                    &mut p,
                    format!(
                        "reconstruction filter `{other}` is not converted (box, tent and \
                         gaussian are; --partial uses Mitsuba's default Gaussian)"
                    ),
                );
                return Ok(None);
            }
        }
        if let Err(e) = filter.build() {
            let e = e.clone();
            self.refuse(&mut p, e);
            return Ok(None);
        }
        self.finish(p, "the reconstruction filter");
        Ok(Some(filter))
    }

    /// The sampler: `independent` (sample count and seed); Mitsuba's other samplers draw the
    /// same expected image with other patterns, and become lumis' independent samples (noted).
    fn sampler(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        match p.kind.as_str() {
            "independent" => {}
            "stratified" | "multijitter" | "orthogonal" | "ldsampler" | "halton" | "hammersley"
            | "sobol" => {
                self.note(
                    p.line,
                    format!(
                        "sampler `{}` becomes lumis' independent samples: the same expected \
                         image, with other noise",
                        p.kind
                    ),
                );
                for ignored in ["jitter", "scramble", "dimension", "randomize"] {
                    p.ignore(ignored);
                }
            }
            other => {
                let other = other.to_string();
                self.refuse(&mut p, format!("sampler `{other}` is not converted"));
                return Ok(());
            }
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
