//! Run-time plugin libraries: BSDFs and textures loaded from a shared library named in a scene's
//! `plugins`.
//!
//! A library is a `cdylib` crate that depends on `lumis-core` and declares its plugins with
//! [`declare_plugin_library!`](crate::declare_plugin_library), which exports one symbol,
//! `LUMIS_PLUGIN_DECLARATION`, holding the plugin API version and the rustc version the library
//! was built with. Rust has no stable ABI, so the loader refuses a library unless both match
//! this program's exactly, before it touches anything else in the declaration. Loaded libraries
//! are never unloaded (their code backs plugin objects for the life of the process). Their
//! plugins are registered with [`crate::registry::register_bsdfs`].

use crate::registry::{BsdfPlugin, TexturePlugin};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Version of the plugin interface (the traits, `BsdfPlugin`, `Params`); bumped on any change.
/// Each version's change is in [`API_CHANGES`].
pub const API_VERSION: u32 = 4;

/// What changed in each version of the plugin interface, for the loader's messages.
pub const API_CHANGES: &[(u32, &str)] = &[
    (
        2,
        "`Bsdf` gained `eval_pdf_batch` and `sample_batch` (a new vtable layout)",
    ),
    (3, "`Emitter` gained `own_shape_never_blocks_samples`"),
    (
        4,
        "every `Bsdf` method takes the shading point's `BsdfContext` (uv, side), `BsdfFlags` is \
         a set of bits with transmission, `BsdfSample` carries η, `BsdfLanes` takes per-lane \
         contexts and parameters, `Params` builds textures and nested BSDFs, and libraries may \
         declare texture plugins",
    ),
];

/// The rustc that built this copy of lumis-core.
pub const RUSTC_VERSION: &str = env!("LUMIS_RUSTC_VERSION");

/// Name of the symbol a plugin library exports.
pub const DECLARATION_SYMBOL: &[u8] = b"LUMIS_PLUGIN_DECLARATION\0";

/// What a plugin library exports. The first three fields have a C layout and are checked before
/// the plugin lists, whose layout is Rust's, are read.
#[repr(C)]
pub struct PluginDeclaration {
    pub api_version: u32,
    pub rustc_version: *const u8,
    pub rustc_version_len: usize,
    pub bsdfs: &'static [BsdfPlugin],
    pub textures: &'static [TexturePlugin],
}

// The declaration is immutable static data.
unsafe impl Sync for PluginDeclaration {}

/// Declares the plugins of a run-time library:
/// `lumis_core::declare_plugin_library!(bsdfs: [MY_BSDF]);` with `MY_BSDF` a `BsdfPlugin`, or
/// `lumis_core::declare_plugin_library!(bsdfs: [MY_BSDF], textures: [MY_TEXTURE]);` with
/// `MY_TEXTURE` a `TexturePlugin`.
#[macro_export]
macro_rules! declare_plugin_library {
    (bsdfs: [$($plugin:expr),* $(,)?]) => {
        $crate::declare_plugin_library!(bsdfs: [$($plugin),*], textures: []);
    };
    (bsdfs: [$($plugin:expr),* $(,)?], textures: [$($texture:expr),* $(,)?]) => {
        #[unsafe(no_mangle)]
        pub static LUMIS_PLUGIN_DECLARATION: $crate::dylib::PluginDeclaration =
            $crate::dylib::PluginDeclaration {
                api_version: $crate::dylib::API_VERSION,
                rustc_version: $crate::dylib::RUSTC_VERSION.as_ptr(),
                rustc_version_len: $crate::dylib::RUSTC_VERSION.len(),
                bsdfs: &[$($plugin),*],
                textures: &[$($texture),*],
            };
    };
}

/// Libraries loaded so far, by canonical path; kept for the life of the process.
static LIBRARIES: Mutex<Vec<(PathBuf, libloading::Library)>> = Mutex::new(Vec::new());
/// Checks a declaration's versions against this program's.
pub fn check_versions(api_version: u32, rustc_version: &str) -> Result<(), String> {
    if api_version != API_VERSION {
        let changes: Vec<String> = API_CHANGES
            .iter()
            .filter(|(version, _)| *version > api_version && *version <= API_VERSION)
            .map(|(version, change)| format!("version {version}: {change}"))
            .collect();
        let since = if changes.is_empty() {
            String::new()
        } else {
            format!(" (since then, {})", changes.join("; "))
        };
        return Err(format!(
            "built for plugin API version {api_version}, but this lumis has version {API_VERSION}{since}: rebuild it against this lumis-core"
        ));
    }
    if rustc_version != RUSTC_VERSION {
        return Err(format!(
            "built with `{rustc_version}`, but this lumis was built with `{RUSTC_VERSION}`: Rust has no stable ABI, rebuild it with the same compiler"
        ));
    }
    Ok(())
}

/// Loads the library at `path` (once per process) and registers its plugins. The error names
/// the problem; callers add the path.
pub fn load_library(path: &Path) -> Result<(), String> {
    let canonical = path
        .canonicalize()
        .map_err(|e| format!("cannot open plugin library: {e}"))?;
    let mut libraries = LIBRARIES.lock().map_err(|_| "plugin registry poisoned")?;
    if libraries.iter().any(|(p, _)| *p == canonical) {
        return Ok(());
    }
    // SAFETY: loading runs the library's initialisers; a lumis plugin library has none beyond
    // Rust's. This is the trust a user gives a plugin by naming it in a scene.
    let library = unsafe { libloading::Library::new(&canonical) }.map_err(|e| {
        // libloading's message is "dlopen failed"; the loader's reason is its source.
        let reason = std::error::Error::source(&e).map_or(e.to_string(), |s| s.to_string());
        format!("cannot load plugin library (not a shared library for this system?): {reason}")
    })?;
    // SAFETY: the symbol, if present, is the static declared by `declare_plugin_library!`; only
    // its C-layout header is read before the versions are known to match.
    let declaration: &'static PluginDeclaration = unsafe {
        let symbol = library
            .get::<*const PluginDeclaration>(DECLARATION_SYMBOL)
            .map_err(|_| {
                "not a lumis plugin library: it does not export LUMIS_PLUGIN_DECLARATION"
                    .to_string()
            })?;
        &**symbol
    };
    // SAFETY: pointer and length describe the library's static RUSTC_VERSION string.
    let rustc = unsafe {
        std::slice::from_raw_parts(declaration.rustc_version, declaration.rustc_version_len)
    };
    check_versions(declaration.api_version, &String::from_utf8_lossy(rustc))?;
    crate::registry::register_bsdfs(declaration.bsdfs)?;
    crate::registry::register_textures(declaration.textures)?;
    libraries.push((canonical, library));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn version_mismatches_are_refused_with_both_versions() {
        assert!(check_versions(API_VERSION, RUSTC_VERSION).is_ok());
        let e = check_versions(API_VERSION + 1, RUSTC_VERSION).unwrap_err();
        assert!(
            e.contains(&format!("API version {}", API_VERSION + 1))
                && e.contains(&format!("has version {API_VERSION}")),
            "{e}"
        );
        // A library of the previous interface is told what changed.
        let e = check_versions(3, RUSTC_VERSION).unwrap_err();
        assert!(
            e.contains("API version 3, but this lumis has version 4")
                && e.contains("`BsdfContext`")
                && e.contains("rebuild it"),
            "{e}"
        );
        let e = check_versions(API_VERSION, "rustc 1.0.0 (a28077b28 2015-05-13)").unwrap_err();
        assert!(
            e.contains("rustc 1.0.0") && e.contains(RUSTC_VERSION),
            "{e}"
        );
    }

    #[test]
    fn missing_files_and_libraries_without_the_symbol_are_refused() {
        let e = load_library(Path::new("/nonexistent/libplugin.so")).unwrap_err();
        assert!(
            e.contains("cannot open plugin library") && e.contains("No such file"),
            "{e}"
        );
        let dir = tempfile::tempdir().unwrap();
        let garbage = dir.path().join("libgarbage.so");
        std::fs::write(&garbage, b"not a shared library").unwrap();
        let e = load_library(&garbage).unwrap_err();
        assert!(e.contains("cannot load plugin library"), "{e}");
    }
}
