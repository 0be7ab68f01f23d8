//! `<bsdf>`: `dielectric`, `thindielectric` and `roughdielectric` become lumis' plugins of the
//! same names, with the same parameters: `int_ior` and `ext_ior` (numbers, or Mitsuba's material
//! names, which lumis reads too), `specular_reflectance` and `specular_transmittance`
//! (constants), and for `roughdielectric` `distribution` (beckmann or ggx), `alpha` (isotropic)
//! (`sample_visible` is dropped with a note: lumis samples visible normals).

use super::Converter;
use super::properties::{Properties, Value};
use lumis_bsdfs::dielectric::{SPECULAR_REFLECTANCE, SPECULAR_TRANSMITTANCE};
use lumis_bsdfs::{dielectric, fresnel, ior, roughdielectric, thindielectric};
use lumis_core::scene::description::PluginSpec;

fn rgb(c: [f64; 3]) -> [f32; 3] {
    c.map(|x| x as f32)
}

impl Converter {
    /// A dielectric BSDF of Mitsuba's (`p.kind` is one of the three), or `None` after a
    /// problem.
    pub(super) fn dielectric(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let kind = match p.kind.as_str() {
            "dielectric" => dielectric::NAME,
            "thindielectric" => thindielectric::NAME,
            _ => roughdielectric::NAME,
        };
        let mut spec = PluginSpec::new(kind);
        let mut converted = true;
        for name in [ior::INT_IOR, ior::EXT_IOR] {
            match p.take(name) {
                Some((Value::Float(x), l)) => spec = self.ior(spec, name, x, l, &mut converted),
                Some((Value::Int(x), l)) => {
                    spec = self.ior(spec, name, x as f64, l, &mut converted)
                }
                Some((Value::Str(s), l)) => match fresnel::named_ior(&s) {
                    Ok(_) => spec = spec.string(name, s.to_lowercase()),
                    Err(e) => {
                        self.problem(l, format!("`{name}`: {e}"));
                        converted = false;
                    }
                },
                Some((_, l)) => {
                    self.problem(l, format!("`{name}` must be a number or a material name"));
                    converted = false;
                }
                // lumis' defaults are Mitsuba's (bk7 inside, air outside).
                None => {}
            }
        }
        for name in [SPECULAR_REFLECTANCE, SPECULAR_TRANSMITTANCE] {
            match p.color(name, 1.0)? {
                Some([1.0, 1.0, 1.0]) => {}
                Some(c) if c.iter().all(|x| (0.0..=1.0).contains(x)) => {
                    spec = spec.rgb(name, rgb(c));
                }
                Some(c) => {
                    self.problem(p.line, format!("`{name}` {c:?} is outside lumis' [0, 1]"));
                    converted = false;
                }
                // A texture: reported with the element's nested objects.
                None => converted = false,
            }
        }
        if kind == roughdielectric::NAME {
            converted &= self.roughness(p, &mut spec);
        }
        Ok(converted.then_some(spec))
    }

    /// `spec` with index of refraction `name` = `x` (line `l`), if lumis takes it.
    fn ior(
        &mut self,
        spec: PluginSpec,
        name: &str,
        x: f64,
        l: u32,
        converted: &mut bool,
    ) -> PluginSpec {
        if !(ior::MIN as f64..=ior::MAX as f64).contains(&x) {
            self.problem(
                l,
                format!(
                    "`{name}` {x} is outside lumis' [{}, {}]",
                    ior::MIN,
                    ior::MAX
                ),
            );
            *converted = false;
            return spec;
        }
        spec.float(name, x as f32)
    }

    /// A rough dielectric's `distribution` and `alpha` into `spec`; false
    /// after a problem.
    fn roughness(&mut self, p: &mut Properties, spec: &mut PluginSpec) -> bool {
        let mut converted = true;
        match p.take("distribution") {
            Some((Value::Str(s), l)) => {
                let s = s.to_lowercase();
                if s == roughdielectric::BECKMANN || s == roughdielectric::GGX {
                    let value = ron::Value::String(s);
                    spec.params
                        .insert(roughdielectric::DISTRIBUTION.into(), value);
                } else {
                    self.problem(l, format!("distribution `{s}` is not converted"));
                    converted = false;
                }
            }
            Some((_, l)) => {
                self.problem(l, "`distribution` must be a string");
                converted = false;
            }
            // Mitsuba's default is lumis' (beckmann).
            None => {}
        }
        let mut alpha = |name: &str| match p.take(name) {
            Some((Value::Float(a), l)) => Some((a, l)),
            Some((Value::Int(a), l)) => Some((a as f64, l)),
            _ => None,
        };
        let alpha = match (alpha("alpha"), alpha("alpha_u"), alpha("alpha_v")) {
            (Some(a), None, None) => Some(a),
            (None, Some(u), Some(v)) if u.0 == v.0 => Some(u),
            (None, None, None) => None,
            _ => {
                self.problem(p.line, "anisotropic roughness is not converted");
                return false;
            }
        };
        if let Some((a, l)) = alpha {
            if !(0.0..=4.0).contains(&a) {
                self.problem(l, format!("alpha {a} is outside lumis' [0, 4]"));
                converted = false;
            } else {
                let value = ron::Value::Number((a as f32).into());
                spec.params.insert(roughdielectric::ALPHA.into(), value);
            }
        }
        // Visible normals or all normals: the same density of directions' mean, another
        // variance; lumis samples visible normals.
        if let Some((_, l)) = p.take("sample_visible") {
            self.note(
                l,
                "`sample_visible` is dropped: lumis samples the visible normals",
            );
        }
        converted
    }
}
