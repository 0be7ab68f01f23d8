//! lumis: a physically based renderer for multiple importance sampling research.
//!
//! This facade re-exports the core ([`lumis_core`]) and links every built-in plugin crate, so
//! that their `inventory` registrations are kept by the linker. Programs and tests that render
//! should go through this crate (or call [`link_plugins`]).

pub use lumis_bsdfs as bsdfs;
pub use lumis_core::*;
pub use lumis_emitters as emitters;
pub use lumis_integrators as integrators;
pub use lumis_textures as textures;

mod binary;
pub mod embedding;
pub mod import;
pub mod same_mean;
pub mod shards;
pub mod study;

/// Makes sure every built-in plugin crate is linked into the final program: a crate none of
/// whose symbols is used may be dropped by the linker together with its registrations.
pub fn link_plugins() {
    lumis_bsdfs::link();
    lumis_emitters::link();
    lumis_integrators::link();
    lumis_textures::link();
}

/// Entry points shared by the fuzz targets (`fuzz/`) and the corpus replay test, so that both
/// exercise exactly the same code. Each returns whether the input was accepted.
pub mod fuzzing {
    use std::path::Path;

    /// Parses and builds a scene from RON text (assets are looked up in a directory that does
    /// not exist, so file-loading errors are exercised too; plugin libraries are not loaded:
    /// arbitrary input must not run arbitrary code, and the loader has its own tests).
    pub fn scene(data: &[u8]) -> bool {
        super::link_plugins();
        let Ok(text) = std::str::from_utf8(data) else {
            return false;
        };
        let path = Path::new("/nonexistent/fuzz.ron");
        match crate::scene::load::parse_description(path, text, &[]) {
            Ok(mut description) => {
                description.plugins.clear();
                crate::scene::load::build_scene(description, path).is_ok()
            }
            Err(_) => false,
        }
    }

    /// Imports a glTF or GLB file from its bytes.
    pub fn gltf(data: &[u8]) -> bool {
        crate::scene::gltf::load_bytes(data, Path::new("/nonexistent"), None).is_ok()
    }

    /// Imports a Wavefront OBJ file from its bytes.
    pub fn obj(data: &[u8]) -> bool {
        crate::scene::obj::parse(data, None).is_ok()
    }

    /// Imports a PLY file from its bytes.
    pub fn ply(data: &[u8]) -> bool {
        crate::scene::ply::parse(data).is_ok()
    }

    /// Converts a Mitsuba XML scene from its bytes (accepted: converted, perhaps with problems;
    /// the files it names are looked for in a folder that does not exist).
    pub fn mitsuba_xml(data: &[u8]) -> bool {
        let Ok(text) = std::str::from_utf8(data) else {
            return false;
        };
        let dir = Path::new("/nonexistent");
        crate::import::convert(text, &dir.join("scene.xml"), dir, &[]).is_ok()
    }

    /// Reads a Mitsuba `.serialized` mesh file from its bytes: its first mesh (accepted), and
    /// its second through the file's table of meshes.
    pub fn serialized(data: &[u8]) -> bool {
        // Run for what it may reveal, not for its verdict.
        let _ = crate::scene::serialized::parse(data, 1);
        crate::scene::serialized::parse(data, 0).is_ok()
    }

    /// Decodes an EXR image from its bytes.
    pub fn exr(data: &[u8]) -> bool {
        crate::image_io::decode_exr_rgb(data).is_ok()
    }

    /// Decodes a texture image (PNG, JPEG or EXR, by its first bytes) as `bitmap` does.
    pub fn texture(data: &[u8]) -> bool {
        lumis_textures::bitmap::Image::decode(data, false).is_ok()
    }
}
