//! `<bsdf>`: `diffuse`, `roughconductor` and `conductor` (with `material="none"`), `twosided`
//! around one of them.

use super::Converter;
use super::properties::{Properties, Value};
use lumis_bsdfs::{diffuse, glossy, mirror};
use lumis_core::scene::description::PluginSpec;
use roxmltree::Node;

/// Mitsuba's BSDF where a shape has none: diffuse, reflectance 0.5.
pub(super) fn default_bsdf() -> PluginSpec {
    PluginSpec::new(diffuse::NAME).rgb(diffuse::REFLECTANCE, [0.5; 3])
}

fn rgb(c: [f64; 3]) -> [f32; 3] {
    c.map(|x| x as f32)
}

impl Converter {
    /// A BSDF element, or `None` after a problem.
    pub(super) fn bsdf(&mut self, node: &Node) -> Result<Option<PluginSpec>, String> {
        let mut p = self.properties(node)?;
        if p.kind == "twosided" {
            let inner: Vec<Node> = p
                .objects
                .iter()
                .copied()
                .filter(|o| o.tag_name().name() == "bsdf")
                .collect();
            if inner.len() != 1 {
                self.problem(
                    p.line,
                    "a twosided BSDF with other than one nested BSDF is not converted",
                );
                return Ok(None);
            }
            self.finish(p, "the twosided BSDF");
            let mut p = self.properties(&inner[0])?;
            let bsdf = self.one_sided_bsdf(&mut p)?;
            let owner = format!("the `{}` BSDF", p.kind);
            self.finish(p, &owner);
            return Ok(bsdf);
        }
        let bsdf = self.one_sided_bsdf(&mut p)?;
        if bsdf.is_some() {
            self.note(
                p.line,
                format!(
                    "BSDF `{}` is one-sided in Mitsuba (black seen from behind); lumis surfaces \
                     reflect on both sides",
                    p.kind
                ),
            );
        }
        let owner = format!("the `{}` BSDF", p.kind);
        self.finish(p, &owner);
        Ok(bsdf)
    }

    /// The BSDF `p` describes (Mitsuba's BSDFs reflect on their front side only), or `None`
    /// after a problem.
    fn one_sided_bsdf(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        self.objects_not_converted(&p.objects, "a BSDF", true);
        match p.kind.as_str() {
            "diffuse" => self.diffuse(p),
            "roughconductor" => self.roughconductor(p),
            "conductor" => self.conductor(p),
            other => {
                let other = other.to_string();
                self.refuse(p, format!("BSDF `{other}` is not converted"));
                Ok(None)
            }
        }
    }

    fn diffuse(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        Ok(p.color("reflectance", 0.5)?
            .map(|r| PluginSpec::new(diffuse::NAME).rgb(diffuse::REFLECTANCE, rgb(r))))
    }

    /// GGX only, with Fresnel 1: lumis `glossy` with F0 = 1 and Mitsuba's separable masking.
    fn roughconductor(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let fresnel_one = self.material_none(p);
        match p.take("distribution") {
            Some((Value::Str(s), _)) if s == "ggx" => {}
            Some((_, l)) => {
                self.problem(
                    l,
                    "microfacet distributions other than ggx are not converted",
                );
                return Ok(None);
            }
            None => {
                self.problem(
                    p.line,
                    "roughconductor without `distribution: ggx` (Mitsuba's default is beckmann) \
                     is not converted",
                );
                return Ok(None);
            }
        }
        let mut alpha = |name: &str| match p.take(name) {
            Some((Value::Float(a), l)) => Some((a, l)),
            Some((Value::Int(a), l)) => Some((a as f64, l)),
            _ => None,
        };
        let (a, l) = match (alpha("alpha"), alpha("alpha_u"), alpha("alpha_v")) {
            (Some(a), None, None) => a,
            (None, Some(u), Some(v)) if u.0 == v.0 => u,
            (None, None, None) => (0.1, p.line),
            _ => {
                self.problem(p.line, "anisotropic roughness is not converted");
                return Ok(None);
            }
        };
        if !(1e-4..=1.0).contains(&a) {
            self.problem(l, format!("alpha {a} is outside lumis' [0.0001, 1]"));
            return Ok(None);
        }
        p.ignore("sample_visible");
        let specular = p.color("specular_reflectance", 1.0)?;
        if specular != Some([1.0; 3]) {
            if specular.is_some() {
                self.problem(
                    p.line,
                    "a specular_reflectance other than 1 is not converted (Schlick's F0 would \
                     not be constant)",
                );
            }
            return Ok(None);
        }
        Ok(fresnel_one.then(|| {
            PluginSpec::new(glossy::NAME)
                .float(glossy::ROUGHNESS, a as f32)
                .rgb(glossy::SPECULAR, [1.0; 3])
                .rgb(glossy::DIFFUSE, [0.0; 3])
                .string(glossy::MASKING, glossy::SEPARABLE)
        }))
    }

    /// A smooth conductor with Fresnel 1: lumis `mirror`.
    fn conductor(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let fresnel_one = self.material_none(p);
        let Some(s) = p.color("specular_reflectance", 1.0)? else {
            return Ok(None);
        };
        Ok(fresnel_one.then(|| PluginSpec::new(mirror::NAME).rgb(mirror::REFLECTANCE, rgb(s))))
    }

    /// Whether a conductor has `material="none"` (Fresnel 1), the only one converted.
    fn material_none(&mut self, p: &mut Properties) -> bool {
        match p.take("material") {
            Some((Value::Str(s), _)) if s == "none" => {
                for k in ["eta", "k"] {
                    if let Some((_, l)) = p.take(k) {
                        self.problem(l, format!("`{k}` with material `none` is not converted"));
                    }
                }
                true
            }
            Some((_, l)) => {
                self.problem(
                    l,
                    "conductor materials other than `none` (Fresnel 1) are not converted",
                );
                false
            }
            None if self.conductor_default_material() == "none" => {
                for k in ["eta", "k"] {
                    if let Some((_, l)) = p.take(k) {
                        self.problem(l, format!("a conductor's `{k}` is not converted"));
                        return false;
                    }
                }
                true
            }
            None => {
                self.problem(
                    p.line,
                    format!(
                        "a conductor without `material` in a Mitsuba {} file is copper (`Cu`), \
                         which is not converted",
                        self.version()
                    ),
                );
                false
            }
        }
    }
}
