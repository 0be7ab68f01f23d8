//! `<bsdf>`: `diffuse`, `conductor`, `roughconductor`, `plastic` and `roughplastic`, and
//! `twosided` around one of them or two (front and back); the `bitmap` and `checkerboard`
//! textures on their parameters (nested, or a `<ref>` to a top-level `<texture>`).
//!
//! Mitsuba's BSDFs that do not transmit light are one-sided (black seen from behind): each is
//! written with `one_sided: true` unless `twosided` wraps it.

use super::Converter;
use super::properties::{Properties, Value, line};
use lumis_bsdfs::{conductor, diffuse, fresnel, plastic, roughconductor, roughplastic, twosided};
use lumis_core::scene::description::PluginSpec;
use lumis_core::scene::references::ONE_SIDED;
use lumis_textures::{bitmap, checkerboard};
use roxmltree::Node;

/// Mitsuba's BSDFs that transmit light: seen from both sides, never made one-sided.
const TRANSMITTING: &[&str] = &["dielectric", "roughdielectric", "thindielectric"];

/// Mitsuba's BSDF where a shape has none: diffuse, reflectance 0.5, one-sided.
pub(super) fn default_bsdf() -> PluginSpec {
    one_sided(PluginSpec::new(diffuse::NAME).rgb(diffuse::REFLECTANCE, [0.5; 3]))
}

fn one_sided(mut spec: PluginSpec) -> PluginSpec {
    spec.params.insert(ONE_SIDED.into(), ron::Value::Bool(true));
    spec
}

/// `spec` with parameter `name` set to `value`.
fn with(mut spec: PluginSpec, name: &str, value: ron::Value) -> PluginSpec {
    spec.params.insert(name.into(), value);
    spec
}

fn number(x: f64) -> ron::Value {
    ron::Value::Number((x as f32).into())
}

/// A colour as a parameter's value (a grey as one number).
fn color(c: [f64; 3]) -> ron::Value {
    if c[0] == c[1] && c[1] == c[2] {
        number(c[0])
    } else {
        ron::Value::Seq(c.iter().map(|&x| number(x)).collect())
    }
}

/// A parameter's value as the importer reads it: `None` after a problem (reported).
type Read = Result<Option<ron::Value>, String>;

impl Converter {
    /// A BSDF element, or `None` after a problem.
    pub(super) fn bsdf(&mut self, node: &Node) -> Result<Option<PluginSpec>, String> {
        let mut p = self.properties(node)?;
        if p.kind == "twosided" {
            return self.twosided(p);
        }
        let bsdf = self.one_bsdf(&mut p)?;
        let kind = p.kind.clone();
        self.finish(p, &format!("the `{kind}` BSDF"));
        Ok(bsdf.map(|spec| {
            if TRANSMITTING.contains(&kind.as_str()) {
                spec
            } else {
                one_sided(spec)
            }
        }))
    }

    /// `twosided` around one BSDF (that BSDF, seen the same from both sides, as lumis BSDFs
    /// are unless one-sided) or two (lumis `twosided` with a front and a back).
    fn twosided(&mut self, p: Properties) -> Result<Option<PluginSpec>, String> {
        let (inner, others): (Vec<Node>, Vec<Node>) = p
            .objects
            .iter()
            .partition(|o| o.tag_name().name() == "bsdf");
        self.objects_not_converted(&others, "a twosided BSDF", true);
        let at = p.line;
        self.finish(p, "the twosided BSDF");
        if inner.is_empty() || inner.len() > 2 {
            self.problem(at, "a twosided BSDF needs one or two nested <bsdf>");
            return Ok(None);
        }
        let mut sides = Vec::new();
        for node in &inner {
            let mut q = self.properties(node)?;
            let kind = q.kind.clone();
            if kind == "twosided" || TRANSMITTING.contains(&kind.as_str()) {
                self.problem(
                    q.line,
                    format!(
                        "a `{kind}` BSDF inside twosided is not converted (Mitsuba refuses it)"
                    ),
                );
                return Ok(None);
            }
            let bsdf = self.one_bsdf(&mut q)?;
            self.finish(q, &format!("the `{kind}` BSDF"));
            let Some(bsdf) = bsdf else {
                return Ok(None);
            };
            sides.push(bsdf);
        }
        let front = sides.remove(0);
        Ok(Some(match sides.pop() {
            None => front,
            Some(back) => PluginSpec::new(twosided::NAME)
                .plugin(twosided::FRONT, front)
                .plugin(twosided::BACK, back),
        }))
    }

    /// The BSDF `p` describes, or `None` after a problem; nested objects it does not read are
    /// reported.
    fn one_bsdf(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let bsdf = match p.kind.as_str() {
            "diffuse" => self.diffuse(p),
            "conductor" => self.conductor(p),
            "roughconductor" => self.roughconductor(p),
            "plastic" => self.plastic(p, false),
            "roughplastic" => self.plastic(p, true),
            "dielectric" | "thindielectric" | "roughdielectric" => self.dielectric(p),
            "principled" | "principledthin" => {
                let message = format!(
                    "BSDF `{}` is not converted: lumis has no principled BSDF (none verified \
                     against Mitsuba's)",
                    p.kind
                );
                self.refuse(p, message);
                Ok(None)
            }
            other => {
                let other = other.to_string();
                self.refuse(p, format!("BSDF `{other}` is not converted"));
                Ok(None)
            }
        };
        let objects = std::mem::take(&mut p.objects);
        self.objects_not_converted(&objects, "a BSDF", true);
        bsdf
    }

    fn diffuse(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let Some(r) = self.color_or_texture(p, "reflectance", 0.5)? else {
            return Ok(None);
        };
        Ok(Some(with(
            PluginSpec::new(diffuse::NAME),
            diffuse::REFLECTANCE,
            r,
        )))
    }

    /// Mitsuba 3's `conductor`; its default `material` is `none`, a perfect mirror, as lumis'.
    fn conductor(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let spec = PluginSpec::new(conductor::NAME);
        self.conductor_parameters(p, spec)
    }

    /// `material` or `eta` and `k`, and `specular_reflectance`, into `spec`.
    fn conductor_parameters(
        &mut self,
        p: &mut Properties,
        mut spec: PluginSpec,
    ) -> Result<Option<PluginSpec>, String> {
        let material = match p.string("material")? {
            None if !p.has("eta") && !p.has("k") => {
                // Files older than Mitsuba 2 meant copper by a conductor without a material.
                let default = self.conductor_default_material();
                if default != conductor::NONE {
                    self.note(
                        p.line,
                        format!(
                            "a conductor without `material` in a Mitsuba {} file is `{default}`, \
                             as that version meant (Mitsuba 3's default is `none`, a mirror)",
                            self.version()
                        ),
                    );
                }
                Some((default.to_string(), p.line))
            }
            material => material,
        };
        if let Some((material, l)) = material
            && material != conductor::NONE
        {
            if let Err(e) = fresnel::named_conductor(&material) {
                self.problem(l, e);
                return Ok(None);
            }
            if p.has("eta") || p.has("k") {
                self.problem(l, "a conductor with both `material` and `eta` or `k`");
                return Ok(None);
            }
            spec = spec.string(conductor::MATERIAL, material);
        }
        for (name, default, lumis) in [
            ("eta", 0.0, conductor::ETA),
            ("k", 1.0, conductor::K),
            ("specular_reflectance", 1.0, conductor::SPECULAR_REFLECTANCE),
        ] {
            if p.has(name) {
                let Some(value) = self.color_or_texture(p, name, default)? else {
                    return Ok(None);
                };
                spec = with(spec, lumis, value);
            }
        }
        Ok(Some(spec))
    }

    /// `roughconductor`: Beckmann when `distribution` is absent, as in Mitsuba.
    fn roughconductor(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let Some(spec) = self.microfacet(p, PluginSpec::new(roughconductor::NAME), true)? else {
            return Ok(None);
        };
        self.conductor_parameters(p, spec)
    }

    /// `distribution` and `alpha` (or equal `alpha_u` and `alpha_v`) into `spec`; `textured`:
    /// whether `alpha` may be a texture.
    fn microfacet(
        &mut self,
        p: &mut Properties,
        mut spec: PluginSpec,
        textured: bool,
    ) -> Result<Option<PluginSpec>, String> {
        match p.string("distribution")? {
            None => {}
            Some((d, _)) if d == roughconductor::BECKMANN || d == roughconductor::GGX => {
                spec = spec.string(roughconductor::DISTRIBUTION, d);
            }
            Some((d, l)) => {
                self.problem(l, format!("microfacet distribution `{d}` is not converted"));
                return Ok(None);
            }
        }
        p.ignore("sample_visible");
        if textured
            && p.objects
                .iter()
                .any(|o| p.name_of(o).as_deref() == Some("alpha"))
        {
            let Some(alpha) = self.texture_parameter(p, "alpha")? else {
                return Ok(None);
            };
            return Ok(Some(with(spec, roughconductor::ALPHA, alpha)));
        }
        let alpha = match (
            p.number("alpha")?,
            p.number("alpha_u")?,
            p.number("alpha_v")?,
        ) {
            (Some(a), None, None) => Some(a),
            (None, Some(u), Some(v)) if u.0 == v.0 => Some(u),
            (None, None, None) => None,
            _ => {
                self.problem(p.line, "anisotropic roughness is not converted");
                return Ok(None);
            }
        };
        if let Some((a, l)) = alpha {
            if !(0.0..=10.0).contains(&a) {
                self.problem(l, format!("alpha {a} is outside lumis' [0, 10]"));
                return Ok(None);
            }
            spec = spec.float(roughconductor::ALPHA, a as f32);
        }
        Ok(Some(spec))
    }

    /// `plastic`, or `roughplastic` (`rough`).
    fn plastic(&mut self, p: &mut Properties, rough: bool) -> Result<Option<PluginSpec>, String> {
        let mut spec = if rough {
            let spec = PluginSpec::new(roughplastic::NAME);
            let Some(spec) = self.microfacet(p, spec, false)? else {
                return Ok(None);
            };
            spec
        } else {
            PluginSpec::new(plastic::NAME)
        };
        let mut iors = [None, None];
        for (ior, (name, lumis)) in iors
            .iter_mut()
            .zip([("int_ior", plastic::INT_IOR), ("ext_ior", plastic::EXT_IOR)])
        {
            let value = match p.take(name) {
                None => continue,
                Some((Value::Float(x), l)) => (x, l),
                Some((Value::Int(n), l)) => (n as f64, l),
                Some((Value::Str(s), l)) => match fresnel::named_ior(&s) {
                    Ok(x) => (x as f64, l),
                    Err(e) => {
                        self.problem(l, e);
                        return Ok(None);
                    }
                },
                Some((_, l)) => return Err(format!("line {l}: `{name}` must be a number")),
            };
            if !(0.01..=10.0).contains(&value.0) {
                self.problem(
                    value.1,
                    format!("`{name}` {} is outside lumis' [0.01, 10]", value.0),
                );
                return Ok(None);
            }
            *ior = Some(value.0);
            spec = spec.float(lumis, value.0 as f32);
        }
        if rough && iors[0].unwrap_or(1.49) == iors[1].unwrap_or(1.000_277) {
            self.problem(
                p.line,
                "a roughplastic whose `int_ior` equals its `ext_ior`",
            );
            return Ok(None);
        }
        for (name, default, lumis) in [
            ("diffuse_reflectance", 0.5, plastic::DIFFUSE_REFLECTANCE),
            ("specular_reflectance", 1.0, plastic::SPECULAR_REFLECTANCE),
        ] {
            if p.has(name) {
                let Some(value) = self.color_or_texture(p, name, default)? else {
                    return Ok(None);
                };
                spec = with(spec, lumis, value);
            }
        }
        match p.take("nonlinear") {
            None => {}
            Some((Value::Bool(b), _)) => {
                spec = with(spec, plastic::NONLINEAR, ron::Value::Bool(b));
            }
            Some((_, l)) => return Err(format!("line {l}: `nonlinear` must be a boolean")),
        }
        Ok(Some(spec))
    }

    /// A colour parameter: a texture of that name (nested, or a `<ref>`), a colour, or the
    /// default.
    fn color_or_texture(&mut self, p: &mut Properties, name: &str, default: f64) -> Read {
        if p.objects
            .iter()
            .any(|o| p.name_of(o).as_deref() == Some(name))
        {
            return self.texture_parameter(p, name);
        }
        Ok(p.color(name, default)?.map(color))
    }

    /// The texture of parameter `name` among `p`'s nested objects (which no longer holds it).
    fn texture_parameter(&mut self, p: &mut Properties, name: &str) -> Read {
        let Some(i) = p
            .objects
            .iter()
            .position(|o| p.name_of(o).as_deref() == Some(name))
        else {
            return Ok(None);
        };
        let node = p.objects.remove(i);
        match node.tag_name().name() {
            "texture" => self.texture(&node),
            "ref" => {
                let id = self.xml.required(&node, "id")?;
                let target = node
                    .document()
                    .root_element()
                    .children()
                    .find(|n| n.has_tag_name("texture") && n.attribute("id") == Some(&id));
                match target {
                    Some(texture) => self.texture(&texture),
                    None => {
                        self.problem(
                            line(&node),
                            format!("reference to `{id}`, which is not a top-level <texture>"),
                        );
                        Ok(None)
                    }
                }
            }
            other => {
                self.problem(
                    line(&node),
                    format!("<{other}> (`{name}`) inside a BSDF is not converted"),
                );
                Ok(None)
            }
        }
    }

    /// A `<texture>` element: `bitmap` or `checkerboard`.
    fn texture(&mut self, node: &Node) -> Read {
        let mut p = self.properties(node)?;
        let objects = std::mem::take(&mut p.objects);
        self.objects_not_converted(&objects, "a texture", true);
        let spec = match p.kind.as_str() {
            "bitmap" => self.bitmap(&mut p)?,
            "checkerboard" => {
                let spec = PluginSpec::new(checkerboard::NAME);
                match (p.color("color0", 0.4)?, p.color("color1", 0.2)?) {
                    (Some(c0), Some(c1)) => Some(
                        spec.rgb(checkerboard::COLOR0, c0.map(|x| x as f32))
                            .rgb(checkerboard::COLOR1, c1.map(|x| x as f32)),
                    ),
                    _ => None,
                }
            }
            other => {
                self.problem(p.line, format!("texture `{other}` is not converted"));
                None
            }
        };
        let spec = match (spec, p.transform("to_uv")?) {
            (Some(spec), Some(m)) => {
                // Mitsuba keeps the 2D affine part of the 4 × 4 matrix (`extract()`).
                let rows = [
                    m.x_axis.x, m.y_axis.x, m.w_axis.x, m.x_axis.y, m.y_axis.y, m.w_axis.y,
                ];
                let mut map = ron::Map::new();
                map.insert(
                    ron::Value::String("matrix".into()),
                    ron::Value::Seq(rows.iter().map(|&x| number(x)).collect()),
                );
                Some(with(spec, bitmap::TO_UV, ron::Value::Map(map)))
            }
            (spec, _) => spec,
        };
        let owner = format!("the `{}` texture", p.kind);
        self.finish(p, &owner);
        Ok(spec.map(PluginSpec::into_value))
    }

    fn bitmap(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let Some((filename, l)) = p.string("filename")? else {
            self.problem(p.line, "a bitmap texture without `filename`");
            return Ok(None);
        };
        let Some(found) = self.asset(&filename, l, "texture file") else {
            return Ok(None);
        };
        let mut spec = PluginSpec::new(bitmap::NAME).string(bitmap::FILENAME, found);
        for (name, lumis, options) in [
            (
                "filter_type",
                bitmap::FILTER_TYPE,
                &[bitmap::BILINEAR, bitmap::NEAREST][..],
            ),
            (
                "wrap_mode",
                bitmap::WRAP_MODE,
                &[bitmap::REPEAT, bitmap::MIRROR, bitmap::CLAMP][..],
            ),
        ] {
            match p.string(name)? {
                None => {}
                Some((v, _)) if options.contains(&v.as_str()) => spec = spec.string(lumis, v),
                Some((v, l)) => {
                    self.problem(l, format!("`{name}` `{v}` is not converted"));
                    return Ok(None);
                }
            }
        }
        match p.take("raw") {
            None => {}
            Some((Value::Bool(b), _)) => spec = with(spec, bitmap::RAW, ron::Value::Bool(b)),
            Some((_, l)) => return Err(format!("line {l}: `raw` must be a boolean")),
        }
        Ok(Some(spec))
    }
}
