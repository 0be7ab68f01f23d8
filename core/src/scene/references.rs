//! The plugins that plugins refer to: textures written inline in a parameter
//! (`reflectance: (type: "checkerboard", ...)`), and BSDFs nested in a BSDF, written inline or
//! named from the scene's `bsdfs` (`front: "gold"`). [`SceneReferences`] builds them through
//! the registry for the scene loader, which also builds the scene's named BSDFs through it, so
//! that a BSDF named by several others is built once and a cycle of names is an error rather
//! than endless recursion.
//!
//! The key [`ONE_SIDED`] of a `bsdfs` entry is the scene's, not the plugin's: it is taken out
//! before the plugin sees its parameters, and recorded with the built BSDF.

use super::description::PluginSpec;
use crate::bsdf::{Bsdf, BsdfFlags};
use crate::error::did_you_mean;
use crate::params::{Params, References, describe_value};
use crate::registry::{self, BsdfPlugin, TexturePlugin};
use crate::texture::Texture;
use ron::Value;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;

/// The key of a `bsdfs` entry that makes the BSDF one-sided: black seen from behind (Mitsuba's
/// default for BSDFs that do not transmit). Two-sided when absent.
pub const ONE_SIDED: &str = "one_sided";

/// A BSDF as the scene built it.
#[derive(Clone)]
pub struct BuiltBsdf {
    pub bsdf: Arc<dyn Bsdf>,
    /// [`Bsdf::flags`], with [`BsdfFlags::SPATIALLY_VARYING`] where the BSDF (or one nested in
    /// it) was given a texture.
    pub flags: BsdfFlags,
    /// Whether the scene made it one-sided ([`ONE_SIDED`]).
    pub one_sided: bool,
}

/// Builds the BSDFs and textures of a scene by name or from their inline descriptions.
pub struct SceneReferences {
    /// Relative paths in the plugins' parameters are resolved against it.
    base_dir: PathBuf,
    /// The scene's `bsdfs`, as written.
    named: BTreeMap<String, PluginSpec>,
    built: RefCell<BTreeMap<String, BuiltBsdf>>,
    /// The named BSDFs being built, outermost first: a name met again is a cycle.
    building: RefCell<Vec<String>>,
}

impl SceneReferences {
    /// For a scene whose `bsdfs` are `named`, with paths relative to `base_dir`.
    pub fn new(base_dir: &Path, named: BTreeMap<String, PluginSpec>) -> Rc<Self> {
        Rc::new(SceneReferences {
            base_dir: base_dir.to_path_buf(),
            named,
            built: RefCell::default(),
            building: RefCell::default(),
        })
    }

    /// With no named BSDFs: builds plugins from their descriptions alone (a BSDF with inline
    /// textures or nested BSDFs, in a test).
    pub fn standalone(base_dir: &Path) -> Rc<Self> {
        Self::new(base_dir, BTreeMap::new())
    }

    /// The BSDF `name` of the scene's `bsdfs`, built on first use. Errors are sentences that
    /// name it.
    pub fn named_bsdf(self: &Rc<Self>, name: &str) -> Result<BuiltBsdf, String> {
        if let Some(built) = self.built.borrow().get(name) {
            return Ok(built.clone());
        }
        let Some(spec) = self.named.get(name) else {
            let defined: Vec<&str> = self.named.keys().map(String::as_str).collect();
            return Err(format!(
                "bsdf `{name}` is not defined{}; defined bsdfs: {}",
                did_you_mean(name, defined.iter().copied()),
                if defined.is_empty() {
                    "none".to_string()
                } else {
                    defined.join(", ")
                }
            ));
        };
        if let Some(start) = self.building.borrow().iter().position(|n| n == name) {
            let mut cycle = self.building.borrow()[start..].to_vec();
            cycle.push(name.to_string());
            return Err(format!(
                "bsdf `{name}` refers back to itself: {}",
                cycle.join(" → ")
            ));
        }
        let mut spec = spec.clone();
        let one_sided = match spec.params.remove(ONE_SIDED) {
            None => false,
            Some(Value::Bool(one_sided)) => one_sided,
            Some(other) => {
                return Err(format!(
                    "bsdf `{name}`: `{ONE_SIDED}` must be true or false, found {}",
                    describe_value(&other)
                ));
            }
        };
        self.building.borrow_mut().push(name.to_string());
        let built = self.build_bsdf(&format!("bsdf `{name}`"), &spec);
        self.building.borrow_mut().pop();
        let (bsdf, flags) = built?;
        if one_sided && flags.transmission() {
            return Err(format!(
                "bsdf `{name}`: `{ONE_SIDED}` applies to BSDFs that only reflect; `{}` transmits \
                 light, and is seen from both sides",
                spec.kind
            ));
        }
        let built = BuiltBsdf {
            bsdf,
            flags,
            one_sided,
        };
        self.built
            .borrow_mut()
            .insert(name.to_string(), built.clone());
        Ok(built)
    }

    /// Builds the BSDF `spec` describes, named `label` in messages ("bsdf `red`"): the plugin by
    /// name, its parameters checked, with its flags as [`BuiltBsdf::flags`] gives them.
    pub fn build_bsdf(
        self: &Rc<Self>,
        label: &str,
        spec: &PluginSpec,
    ) -> Result<(Arc<dyn Bsdf>, BsdfFlags), String> {
        let plugin =
            registry::find::<BsdfPlugin>(&spec.kind).map_err(|e| format!("{label}: {e}"))?;
        let mut params = self.params(format!("{label} ({})", spec.kind), plugin.params, spec)?;
        let bsdf = (plugin.create)(&mut params).map_err(|e| e.to_string())?;
        let mut flags = bsdf.flags();
        if params.uses_textures() {
            flags |= BsdfFlags::SPATIALLY_VARYING;
        }
        params.finish().map_err(|e| e.to_string())?;
        Ok((bsdf, flags))
    }

    /// The parameters of a plugin instance, which refer to others through `self`.
    fn params(
        self: &Rc<Self>,
        label: String,
        specs: &'static [crate::params::ParamSpec],
        spec: &PluginSpec,
    ) -> Result<Params, String> {
        Ok(Params::new(label, specs, spec.params.clone())
            .map_err(|e| e.to_string())?
            .with_base_dir(&self.base_dir)
            .with_references(self.clone()))
    }
}

/// The plugin description written inline as `value`.
fn inline_spec(value: &Value) -> Result<PluginSpec, String> {
    value
        .clone()
        .into_rust::<PluginSpec>()
        .map_err(|e| match e {
            ron::Error::Message(message) => message,
            other => other.to_string(),
        })
}

impl References for SceneReferences {
    fn texture(self: Rc<Self>, _label: &str, value: &Value) -> Result<Arc<dyn Texture>, String> {
        let spec = inline_spec(value)?;
        let plugin = registry::find::<TexturePlugin>(&spec.kind)?;
        let mut params = self.params(format!("texture ({})", spec.kind), plugin.params, &spec)?;
        let texture = (plugin.create)(&mut params).map_err(|e| e.to_string())?;
        params.finish().map_err(|e| e.to_string())?;
        Ok(texture)
    }

    fn bsdf(
        self: Rc<Self>,
        _label: &str,
        value: &Value,
    ) -> Result<(Arc<dyn Bsdf>, BsdfFlags), String> {
        if let Value::String(name) = value {
            let built = self.named_bsdf(name)?;
            return Ok((built.bsdf, built.flags));
        }
        let spec = inline_spec(value)?;
        if spec.params.contains_key(ONE_SIDED) {
            return Err(format!(
                "`{ONE_SIDED}` is a key of the scene's `bsdfs` entries (the BSDFs shapes use), \
                 not of a nested BSDF"
            ));
        }
        self.build_bsdf("bsdf", &spec)
    }
}
