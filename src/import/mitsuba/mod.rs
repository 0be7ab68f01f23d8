//! The Mitsuba 3 XML reader: builds a [`SceneDescription`] and writes it as RON.
//!
//! One file per Mitsuba plugin family, each an `impl Converter` block with one function per
//! plugin type it converts: `integrator.rs`, `sensor.rs` (with the film and the sampler),
//! `bsdf.rs` (with `dielectric.rs` for the dielectrics), `shape.rs`, `emitter.rs`. `properties.rs` reads attributes and properties (every
//! property no converter reads is reported with its line), `transform.rs` reads `<transform>`,
//! `paths.rs` rewrites file names. Plugin parameters are named through the plugin crates'
//! constants (e.g. `diffuse::REFLECTANCE`), schema fields through the description's types.

mod bsdf;
mod dielectric;
mod emitter;
mod integrator;
mod paths;
mod properties;
mod sensor;
mod shape;
mod transform;

use lumis_core::scene::description::{
    CameraDescription, FilmDescription, PluginSpec, SamplerDescription, SceneDescription,
    ShapeDescription,
};
use properties::{Properties, Xml, line};
use roxmltree::Node;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Something in the XML file that has no lumis equivalent.
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// Line in the XML file, from 1.
    pub line: u32,
    pub message: String,
}

/// The converted scene, what could not be converted, and notes on conventions.
#[derive(Clone, Debug)]
pub struct Conversion {
    /// The scene file's text: `description` as RON.
    pub ron: String,
    pub description: SceneDescription,
    pub problems: Vec<Problem>,
    /// Differences of convention that do not change the expected image, with their lines.
    pub notes: Vec<Problem>,
}

/// Converts Mitsuba XML text. Relative file names in it are relative to `xml_dir`, and are
/// written relative to `out_dir` (where the RON file goes). `defines` override the file's
/// `default` parameters (as `mitsuba -D name=value`). Fails on malformed XML or an undefined
/// `$` parameter; everything else that cannot be converted is listed in `problems`.
pub fn convert(
    xml: &str,
    xml_dir: &Path,
    out_dir: &Path,
    defines: &[(String, String)],
) -> Result<Conversion, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("not valid XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "scene" {
        return Err(format!(
            "line {}: the root element is <{}>, not <scene>",
            line(&root),
            root.tag_name().name()
        ));
    }
    let mut c = Converter {
        xml: Xml::new(&root, defines)?,
        xml_dir: xml_dir.to_path_buf(),
        out_dir: out_dir.to_path_buf(),
        report: Report::default(),
        camera: None,
        film: None,
        sampler: None,
        integrator: None,
        bsdfs: BTreeMap::new(),
        shapes: Vec::new(),
        emitters: Vec::new(),
        anonymous: 0,
    };
    c.scene(&root)?;
    let description = c.description(&root);
    let ron = description
        .to_ron()
        .map_err(|e| format!("cannot write the scene as RON: {e}"))?;
    Ok(Conversion {
        ron: format!("// Converted from a Mitsuba 3 scene by `lumis import`.\n{ron}"),
        description,
        problems: c.report.problems,
        notes: c.report.notes,
    })
}

/// What could not be converted, and the notes, in the order found.
#[derive(Default)]
struct Report {
    problems: Vec<Problem>,
    notes: Vec<Problem>,
}

impl Report {
    fn problem(&mut self, line: u32, message: impl Into<String>) {
        self.problems.push(Problem {
            line,
            message: message.into(),
        });
    }

    fn note(&mut self, line: u32, message: impl Into<String>) {
        self.notes.push(Problem {
            line,
            message: message.into(),
        });
    }
}

/// The conversion under way: the parts of the scene converted so far.
struct Converter {
    xml: Xml,
    xml_dir: PathBuf,
    out_dir: PathBuf,
    report: Report,
    camera: Option<CameraDescription>,
    film: Option<FilmDescription>,
    sampler: Option<SamplerDescription>,
    integrator: Option<PluginSpec>,
    bsdfs: BTreeMap<String, PluginSpec>,
    shapes: Vec<ShapeDescription>,
    emitters: Vec<PluginSpec>,
    /// Nested BSDFs converted so far (names those without an `id`).
    anonymous: usize,
}

impl Converter {
    fn problem(&mut self, line: u32, message: impl Into<String>) {
        self.report.problem(line, message);
    }

    fn note(&mut self, line: u32, message: impl Into<String>) {
        self.report.note(line, message);
    }

    /// Reads a plugin element's properties.
    fn properties<'a, 'input>(
        &mut self,
        node: &Node<'a, 'input>,
    ) -> Result<Properties<'a, 'input>, String> {
        properties::read(node, &self.xml, &mut self.report)
    }

    /// Reports every property of `p` that was not read, as not converted by `owner`.
    fn finish(&mut self, p: Properties, owner: &str) {
        p.finish(owner, &mut self.report);
    }

    /// Reports each of `objects` (nested plugins) as not converted `inside` its element, e.g.
    /// "<texture> (`reflectance`) inside a BSDF is not converted" (`named`: with its name).
    fn objects_not_converted(&mut self, objects: &[Node], inside: &str, named: bool) {
        for o in objects {
            let name = match o.attribute("name") {
                Some(n) if named => format!(" (`{n}`)"),
                _ => String::new(),
            };
            self.problem(
                line(o),
                format!(
                    "<{}>{name} inside {inside} is not converted",
                    o.tag_name().name()
                ),
            );
        }
    }

    fn scene(&mut self, root: &Node) -> Result<(), String> {
        for node in root.children().filter(Node::is_element) {
            let at = line(&node);
            match node.tag_name().name() {
                "default" => {}
                "integrator" => self.integrator(&node)?,
                "sensor" => self.sensor(&node)?,
                "bsdf" => {
                    let Some(id) = self.xml.attribute(&node, "id")? else {
                        self.problem(at, "a top-level <bsdf> without `id` is never used");
                        continue;
                    };
                    if let Some(bsdf) = self.bsdf(&node)? {
                        self.bsdfs.insert(id, bsdf);
                    }
                }
                "shape" => self.shape(&node)?,
                // Converted where a BSDF refers to it (`bsdf.rs`).
                "texture" if node.attribute("id").is_some() => {}
                "emitter" => self.emitter(&node)?,
                other => self.problem(at, format!("<{other}> is not converted")),
            }
        }
        Ok(())
    }

    /// The scene, with Mitsuba's defaults for the parts the XML does not give.
    fn description(&mut self, root: &Node) -> SceneDescription {
        let at = line(root);
        let camera = self.camera.take().unwrap_or_else(|| {
            self.problem(at, "the scene has no convertible perspective sensor");
            CameraDescription {
                position: Some([0.0; 3]),
                target: Some([0.0, 0.0, 1.0]),
                up: None,
                fov: Some(45.0),
                gltf: None,
                name: None,
            }
        });
        let film = self.film.take().unwrap_or(FilmDescription {
            width: sensor::DEFAULT_WIDTH,
            height: sensor::DEFAULT_HEIGHT,
            output: None,
            crop: None,
            exposure: 0.0,
        });
        let sampler = self.sampler.take().unwrap_or(SamplerDescription {
            spp: sensor::DEFAULT_SPP,
            seed: 0,
            jitter: true,
        });
        let integrator = self.integrator.take().unwrap_or_else(|| {
            self.note(
                at,
                "no <integrator>: Mitsuba's default, `path`, becomes lumis `path` as a `path` \
                 element does",
            );
            integrator::mitsuba_path()
        });
        SceneDescription {
            camera,
            film,
            sampler,
            integrator,
            bsdfs: std::mem::take(&mut self.bsdfs),
            shapes: std::mem::take(&mut self.shapes),
            emitters: std::mem::take(&mut self.emitters),
            plugins: Vec::new(),
        }
    }

    /// A file name in the XML, as the RON file must write it.
    fn path(&self, name: &str) -> String {
        paths::as_written_from(name, &self.xml_dir, &self.out_dir)
    }
}
