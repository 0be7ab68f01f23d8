//! Plugin registries. Each built-in plugin registers itself from its own file:
//!
//! ```ignore
//! inventory::submit! { BsdfPlugin { name: "diffuse", description: "...", params: PARAMS, create } }
//! ```
//!
//! The facade crate links every plugin crate so the linker keeps these registrations. BSDFs
//! and textures may also be registered at run time ([`register_bsdfs`], [`register_textures`],
//! used by [`crate::dylib`], which depends on this module and not the other way round).

use crate::bsdf::Bsdf;
use crate::emitter::{Emitter, EmitterContext};
use crate::error::did_you_mean;
use crate::integrator::Integrator;
use crate::params::{ParamSpec, Params, PluginError};
use crate::texture::Texture;
use std::sync::{Arc, RwLock};

/// Builds an emitter from its parameters and, for area emitters, its shape.
pub type CreateEmitter = fn(&mut Params, &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError>;

pub struct BsdfPlugin {
    pub name: &'static str,
    pub description: &'static str,
    pub params: &'static [ParamSpec],
    pub create: fn(&mut Params) -> Result<Arc<dyn Bsdf>, PluginError>,
}

pub struct EmitterPlugin {
    pub name: &'static str,
    pub description: &'static str,
    pub params: &'static [ParamSpec],
    pub create: CreateEmitter,
}

pub struct TexturePlugin {
    pub name: &'static str,
    pub description: &'static str,
    pub params: &'static [ParamSpec],
    pub create: fn(&mut Params) -> Result<Arc<dyn Texture>, PluginError>,
}

pub struct IntegratorPlugin {
    pub name: &'static str,
    pub description: &'static str,
    pub params: &'static [ParamSpec],
    pub create: fn(&mut Params) -> Result<Box<dyn Integrator>, PluginError>,
}

inventory::collect!(BsdfPlugin);
inventory::collect!(EmitterPlugin);
inventory::collect!(TexturePlugin);
inventory::collect!(IntegratorPlugin);

/// Name, description and parameters, common to the three kinds.
pub trait PluginInfo: Sized + 'static {
    const KIND: &'static str;
    fn name(&self) -> &'static str;
    fn description(&self) -> &'static str;
    fn params(&self) -> &'static [ParamSpec];
    /// Plugins of this kind registered by run-time libraries.
    fn loaded() -> Vec<&'static Self>;
}

macro_rules! plugin_info {
    ($t:ty, $kind:literal, $loaded:expr) => {
        impl PluginInfo for $t {
            const KIND: &'static str = $kind;
            fn name(&self) -> &'static str {
                self.name
            }
            fn description(&self) -> &'static str {
                self.description
            }
            fn params(&self) -> &'static [ParamSpec] {
                self.params
            }
            fn loaded() -> Vec<&'static Self> {
                $loaded
            }
        }
    };
}
plugin_info!(BsdfPlugin, "bsdf", loaded_bsdfs());
plugin_info!(EmitterPlugin, "emitter", Vec::new());
plugin_info!(TexturePlugin, "texture", loaded_textures());
plugin_info!(IntegratorPlugin, "integrator", Vec::new());

/// BSDF and texture plugins registered at run time, in the order they were registered.
static LOADED_BSDFS: RwLock<Vec<&'static BsdfPlugin>> = RwLock::new(Vec::new());
static LOADED_TEXTURES: RwLock<Vec<&'static TexturePlugin>> = RwLock::new(Vec::new());

fn loaded_bsdfs() -> Vec<&'static BsdfPlugin> {
    LOADED_BSDFS.read().map(|v| v.clone()).unwrap_or_default()
}

fn loaded_textures() -> Vec<&'static TexturePlugin> {
    LOADED_TEXTURES
        .read()
        .map(|v| v.clone())
        .unwrap_or_default()
}

/// Registers plugins of one kind at run time into `loaded`. Refuses them all, naming the
/// first, if one has the name of a plugin of that kind that is already registered.
fn register<P: PluginInfo + inventory::Collect>(
    loaded: &RwLock<Vec<&'static P>>,
    plugins: &'static [P],
) -> Result<(), String> {
    let mut loaded = loaded.write().map_err(|_| "plugin registry poisoned")?;
    let taken = |name: &str| {
        builtin::<P>().iter().any(|p| p.name() == name) || loaded.iter().any(|p| p.name() == name)
    };
    if let Some(plugin) = plugins.iter().find(|p| taken(p.name())) {
        return Err(format!(
            "its {} `{}` has the name of a plugin that is already registered",
            P::KIND,
            plugin.name()
        ));
    }
    loaded.extend(plugins);
    Ok(())
}

/// Registers BSDF plugins at run time (from a plugin library, or a test). Refuses them all,
/// naming the first, if one has the name of a plugin that is already registered.
pub fn register_bsdfs(bsdfs: &'static [BsdfPlugin]) -> Result<(), String> {
    register(&LOADED_BSDFS, bsdfs)
}

/// Registers texture plugins at run time, as [`register_bsdfs`].
pub fn register_textures(textures: &'static [TexturePlugin]) -> Result<(), String> {
    register(&LOADED_TEXTURES, textures)
}

/// The built-in plugins of one kind, sorted by name.
pub fn builtin<P: PluginInfo + inventory::Collect>() -> Vec<&'static P> {
    let mut v: Vec<&'static P> = inventory::iter::<P>.into_iter().collect();
    v.sort_by_key(|p| p.name());
    v
}

/// All plugins of one kind that are registered (built in or loaded from libraries), by name.
pub fn plugins<P: PluginInfo + inventory::Collect>() -> Vec<&'static P> {
    let mut v = builtin::<P>();
    v.extend(P::loaded());
    v.sort_by_key(|p| p.name());
    v
}

/// The plugin of that kind and name, or an error listing the known ones and the closest name.
pub fn find<P: PluginInfo + inventory::Collect>(name: &str) -> Result<&'static P, String> {
    let all = plugins::<P>();
    all.iter()
        .copied()
        .find(|p| p.name() == name)
        .ok_or_else(|| {
            let known: Vec<&str> = all.iter().map(|p| p.name()).collect();
            format!(
                "unknown {} plugin `{name}`{}; known {} plugins: {}",
                P::KIND,
                did_you_mean(name, known.iter().copied()),
                P::KIND,
                known.join(", ")
            )
        })
}

fn param_line(p: &ParamSpec) -> String {
    let unit = if p.unit.is_empty() {
        String::new()
    } else {
        format!(" [{}]", p.unit)
    };
    let range = p.range_text();
    let range = if range.is_empty() {
        String::new()
    } else {
        format!(", valid: {range}")
    };
    format!(
        "    {:<14} {:<9} default {}{}{} — {}\n",
        p.name,
        p.type_name(),
        p.default_text(),
        range,
        unit,
        p.description
    )
}

fn section_text<P: PluginInfo + inventory::Collect>(title: &str) -> String {
    let mut s = format!("{title}:\n");
    for p in builtin::<P>() {
        s += &format!("  {} — {}\n", p.name(), p.description());
        for param in p.params() {
            s += &param_line(param);
        }
    }
    s
}

/// Every built-in plugin with its parameters, as plain text (`lumis plugins`).
pub fn plugins_text() -> String {
    [
        section_text::<BsdfPlugin>("BSDFs"),
        section_text::<EmitterPlugin>("Emitters"),
        section_text::<TexturePlugin>("Textures"),
        section_text::<IntegratorPlugin>("Integrators"),
    ]
    .join("\n")
}

fn section_markdown<P: PluginInfo + inventory::Collect>(title: &str) -> String {
    let mut s = format!("## {title}\n");
    for p in builtin::<P>() {
        s += &format!("\n### `{}`\n\n{}\n\n", p.name(), p.description());
        if p.params().is_empty() {
            s += "No parameters.\n";
            continue;
        }
        s += "| parameter | type | default | valid | unit | meaning |\n|---|---|---|---|---|---|\n";
        for q in p.params() {
            s += &format!(
                "| `{}` | {} | `{}` | {} | {} | {} |\n",
                q.name,
                q.type_name(),
                q.default_text(),
                q.range_text(),
                q.unit,
                q.description
            );
        }
    }
    s
}

/// The plugin reference as Markdown (`lumis plugins --markdown`, stored as docs/plugins.md).
pub fn plugins_markdown() -> String {
    format!(
        "# Plugin reference\n\nGenerated by `lumis plugins --markdown`; a test checks that this file is current.\n\n{}\n{}\n{}\n{}",
        section_markdown::<BsdfPlugin>("BSDFs"),
        section_markdown::<EmitterPlugin>("Emitters"),
        section_markdown::<TexturePlugin>("Textures"),
        section_markdown::<IntegratorPlugin>("Integrators")
    )
}
