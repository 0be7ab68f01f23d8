//! The Mitsuba XML reader: builds a [`SceneDescription`] and writes it as RON.
//!
//! One file per Mitsuba plugin family, each an `impl Converter` block with one function per
//! plugin type it converts: `integrator.rs`, `sensor.rs` (with the film, its filter and the
//! sampler), `bsdf.rs` (with `dielectric.rs` for the dielectrics), `shape.rs`, `emitter.rs`. `files.rs` reads the main file and its
//! includes (with `<default>` and `<path>`), `properties.rs` reads attributes and properties
//! (upgrading the names of files older than Mitsuba 2; every property no converter reads is
//! reported with its line), `spectrum.rs` turns spectra into RGB as Mitsuba's RGB variants do,
//! `transform.rs` reads `<transform>`, `paths.rs` rewrites file names. Plugin parameters are
//! named through the plugin crates' constants (e.g. `diffuse::REFLECTANCE`), schema fields
//! through the description's types.
//!
//! Refusals: [`Converter::problem`] records one problem at a line of the file being read;
//! [`Converter::refuse`] refuses a whole element with one problem, after which none of its
//! properties or nested objects is reported again. A shape whose BSDF is refused keeps its
//! geometry with Mitsuba's default BSDF (noted), so `--partial` never drops geometry silently.

mod bsdf;
mod dielectric;
mod emitter;
/// The main file and its includes, versions, and `$name` parameters.
pub mod files;
mod integrator;
/// File names rewritten for the RON scene's folder.
pub mod paths;
/// Attributes and properties, and the names of files older than Mitsuba 2.
pub mod properties;
mod sensor;
mod shape;
/// Spectra to RGB, as Mitsuba's RGB variants make them.
pub mod spectrum;
mod transform;

pub use files::Version;

use files::Sources;
use lumis_core::scene::description::{
    CameraDescription, FilmDescription, PluginSpec, SamplerDescription, SceneDescription,
    ShapeDescription,
};
use lumis_emitters::{SCALE, directional, point, spot};
use properties::{Properties, Xml, line};
use roxmltree::{Document, Node};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Something in the XML files that has no lumis equivalent (or a note on a convention).
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// The XML file (the main file or one it includes).
    pub file: PathBuf,
    /// Line in that file, from 1.
    pub line: u32,
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.file.display(), self.line, self.message)
    }
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
    /// The scene has no convertible sensor: `description` has a stand-in camera, and no scene
    /// is written, even with `--partial`.
    pub camera_missing: bool,
}

/// Converts the Mitsuba XML file at `path`, whose text is read here (see [`convert`]).
pub fn convert_file(
    path: &Path,
    out_dir: &Path,
    defines: &[(String, String)],
) -> Result<Conversion, String> {
    let xml = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    convert(&xml, path, out_dir, defines)
}

/// Converts Mitsuba XML text, that of the file at `path`: relative file names in it are
/// relative to that file's folder (and its `<path>` folders), included files are read from
/// disk, and names are written relative to `out_dir` (where the RON file goes). `defines`
/// override the file's `default` parameters (as `mitsuba -D name=value`). Fails, naming the
/// file and line, on malformed XML, an include that cannot be read or makes a cycle, or an
/// undefined `$` parameter; everything else that cannot be converted is listed in `problems`.
pub fn convert(
    xml: &str,
    path: &Path,
    out_dir: &Path,
    defines: &[(String, String)],
) -> Result<Conversion, String> {
    let sources = Sources::read(path, xml.to_string(), defines)?;
    let docs = sources
        .files
        .iter()
        .map(|f| Document::parse(&f.text))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| format!("not valid XML: {e}"))?;
    let root = docs[0].root_element();
    if root.tag_name().name() != "scene" {
        return Err(format!(
            "{}:{}: the root element is <{}>, not <scene>",
            path.display(),
            line(&root),
            root.tag_name().name()
        ));
    }
    let mut c = Converter {
        xml: Xml::new(sources.parameters.clone()),
        files: sources
            .files
            .iter()
            .map(|f| (f.path.clone(), f.version))
            .collect(),
        file: 0,
        error_file: None,
        out_dir: out_dir.to_path_buf(),
        report: Report {
            file: path.to_path_buf(),
            ..Report::default()
        },
        camera: None,
        film: None,
        sampler: None,
        integrator: None,
        delta_light_factor: None,
        integrator_refused: false,
        bsdfs: BTreeMap::new(),
        refused_bsdfs: BTreeMap::new(),
        area_emitters: BTreeMap::new(),
        ids: BTreeMap::new(),
        shapes: Vec::new(),
        emitters: Vec::new(),
        anonymous: 0,
        includes: sources.includes.clone(),
        search: sources.search.clone(),
    };
    let outcome = c.scene_file(&docs, &root);
    if let Err(e) = outcome {
        let file = &c.files[c.error_file.unwrap_or(c.file)].0;
        return Err(located(&e, file));
    }
    let description = c.description(&root);
    let ron = description
        .to_ron()
        .map_err(|e| format!("cannot write the scene as RON: {e}"))?;
    Ok(Conversion {
        ron: format!("// Converted from a Mitsuba scene by `lumis import`.\n{ron}"),
        description,
        problems: c.report.problems,
        notes: c.report.notes,
        camera_missing: c.camera.is_none() && c.report.camera_missing,
    })
}

/// A fatal error's message `e` ("line N: ..." of `file`, or already located) as
/// "FILE:N: ...".
fn located(e: &str, file: &Path) -> String {
    if let Some(rest) = e.strip_prefix("line ")
        && let Some((number, message)) = rest.split_once(':')
        && number.chars().all(|c| c.is_ascii_digit())
    {
        return format!("{}:{number}:{message}", file.display());
    }
    if e.starts_with(&file.display().to_string()) {
        return e.to_string();
    }
    format!("{}: {e}", file.display())
}

/// What could not be converted, and the notes, in the order found.
#[derive(Default)]
struct Report {
    /// The file being read, which problems and notes are in.
    file: PathBuf,
    problems: Vec<Problem>,
    notes: Vec<Problem>,
    camera_missing: bool,
}

impl Report {
    fn problem(&mut self, line: u32, message: impl Into<String>) {
        self.problems.push(Problem {
            file: self.file.clone(),
            line,
            message: message.into(),
        });
    }

    fn note(&mut self, line: u32, message: impl Into<String>) {
        let note = Problem {
            file: self.file.clone(),
            line,
            message: message.into(),
        };
        // The same note on the same line once (an element met through two references).
        if !self.notes.contains(&note) {
            self.notes.push(note);
        }
    }
}

/// Where an `id` was defined, and by what element.
#[derive(Clone, Debug)]
struct Definition {
    tag: String,
    kind: String,
    file: usize,
    line: u32,
}

/// The conversion under way: the parts of the scene converted so far.
struct Converter {
    xml: Xml,
    /// Every XML file of the scene (the main file first) and its version.
    files: Vec<(PathBuf, Version)>,
    /// The file being read.
    file: usize,
    /// The file a fatal error was raised in, if not `file`.
    error_file: Option<usize>,
    out_dir: PathBuf,
    report: Report,
    camera: Option<CameraDescription>,
    film: Option<FilmDescription>,
    sampler: Option<SamplerDescription>,
    integrator: Option<PluginSpec>,
    /// Mitsuba's `direct` with `emitter_samples` ≠ 1 shows each delta light that many times
    /// (`integrator.rs`): the factor and the integrator's line.
    delta_light_factor: Option<(i64, u32)>,
    /// An `<integrator>` was there but could not be converted.
    integrator_refused: bool,
    bsdfs: BTreeMap<String, PluginSpec>,
    /// BSDFs with an `id` that were refused: (file, line).
    refused_bsdfs: BTreeMap<String, (usize, u32)>,
    /// `area` emitters given at the scene's level with an `id`, for shapes that refer to them.
    area_emitters: BTreeMap<String, PluginSpec>,
    /// Every element with an `id`, for messages about references.
    ids: BTreeMap<String, Definition>,
    shapes: Vec<ShapeDescription>,
    emitters: Vec<PluginSpec>,
    /// Nested BSDFs converted so far (names those without an `id`).
    anonymous: usize,
    /// (file, byte offset of an `<include>` in it) → the file it includes.
    includes: HashMap<(usize, usize), usize>,
    /// Folders searched for asset files, first first.
    search: Vec<PathBuf>,
}

impl Converter {
    fn problem(&mut self, line: u32, message: impl Into<String>) {
        self.report.problem(line, message);
    }

    fn note(&mut self, line: u32, message: impl Into<String>) {
        self.report.note(line, message);
    }

    /// Refuses the element `p` as a whole: one problem at its line, and none for its
    /// properties and nested objects, which [`finish`](Self::finish) then leaves alone.
    fn refuse(&mut self, p: &mut Properties, message: impl Into<String>) {
        p.refused = true;
        self.problem(p.line, message);
    }

    /// The version of the file being read.
    fn version(&self) -> Version {
        self.files[self.file].1
    }

    /// The `material` a `conductor` or `roughconductor` has when it names none: `Cu` in files
    /// older than Mitsuba 2 (what they meant), `none` (a perfect mirror) in Mitsuba 3's.
    fn conductor_default_material(&self) -> &'static str {
        if self.version().is_legacy() {
            "Cu"
        } else {
            "none"
        }
    }

    /// Reads a plugin element's properties (names upgraded in files older than Mitsuba 2).
    fn properties<'a, 'input>(
        &mut self,
        node: &Node<'a, 'input>,
    ) -> Result<Properties<'a, 'input>, String> {
        let version = self.version();
        properties::read(node, &self.xml, &mut self.report, version)
    }

    /// Reports every property of `p` that was not read, as not converted by `owner` (none if
    /// `p` was refused as a whole).
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

    /// Reads the scene whose main file's root is `root`: the `id`s of every scene-level
    /// element first, then the BSDFs, textures and area emitters, then the rest, so that a
    /// reference may come before what it names (Mitsuba resolves references once every file is
    /// read).
    fn scene_file(&mut self, docs: &[Document], root: &Node) -> Result<(), String> {
        self.collect_ids(docs, 0, root)?;
        self.in_pass(docs, 0, root, true)?;
        self.in_pass(docs, 0, root, false)
    }

    /// The scene-level elements of file `index` (whose root is `root`): a `<scene>`'s
    /// children, or the root itself (an included file of another root is one element).
    fn scene_level<'a, 'input>(root: &Node<'a, 'input>) -> Vec<Node<'a, 'input>> {
        if root.tag_name().name() == "scene" {
            root.children().filter(Node::is_element).collect()
        } else {
            vec![*root]
        }
    }

    /// The file an `<include>` of the file being read brings in.
    fn included(&self, node: &Node) -> Option<usize> {
        (node.tag_name().name() == "include")
            .then(|| self.includes.get(&(self.file, node.range().start)))
            .flatten()
            .copied()
    }

    /// Runs `f` with file `index` as the file being read; a fatal error keeps the file it was
    /// raised in.
    fn reading<T>(
        &mut self,
        index: usize,
        f: impl FnOnce(&mut Self) -> Result<T, String>,
    ) -> Result<T, String> {
        let outer = std::mem::replace(&mut self.file, index);
        self.report.file = self.files[index].0.clone();
        let result = f(self);
        if result.is_err() && self.error_file.is_none() {
            self.error_file = Some(index);
        }
        self.file = outer;
        self.report.file = self.files[outer].0.clone();
        result
    }

    /// Records the `id`s of file `index`'s scene-level elements and its includes'.
    fn collect_ids(&mut self, docs: &[Document], index: usize, root: &Node) -> Result<(), String> {
        self.reading(index, |c| {
            for node in Self::scene_level(root) {
                match c.included(&node) {
                    Some(included) => {
                        c.collect_ids(docs, included, &docs[included].root_element())?
                    }
                    None => c.define(&node)?,
                }
            }
            Ok(())
        })
    }

    /// One pass over file `index` and its includes: its referable elements (BSDFs, textures and
    /// area emitters, `first_pass`) or the others.
    fn in_pass(
        &mut self,
        docs: &[Document],
        index: usize,
        root: &Node,
        first_pass: bool,
    ) -> Result<(), String> {
        self.reading(index, |c| {
            if first_pass && c.version().is_legacy() {
                c.note(
                    line(root),
                    format!(
                        "a Mitsuba {} file (before 2.0): read as Mitsuba 3 reads it, property \
                         names in snake_case (`toWorld` is `to_world`) and diffuse \
                         `diffuseReflectance` as `reflectance`; where its defaults differ from \
                         Mitsuba 3's, the file's are kept (a conductor without `material` is \
                         copper, `Cu`, not Mitsuba 3's mirror, `none`)",
                        c.version()
                    ),
                );
            }
            for node in Self::scene_level(root) {
                if let Some(included) = c.included(&node) {
                    c.in_pass(docs, included, &docs[included].root_element(), first_pass)?;
                } else if Self::referable(&node) == first_pass {
                    c.element(&node)?;
                }
            }
            Ok(())
        })
    }

    /// Whether a scene-level element is one that shapes refer to (a BSDF, a texture, an `area`
    /// emitter), read in the first pass.
    fn referable(node: &Node) -> bool {
        match node.tag_name().name() {
            "bsdf" | "texture" => true,
            "emitter" => node.attribute("type") == Some("area"),
            _ => false,
        }
    }

    /// Records the `id` of a scene-level element; a second definition is an error (as in
    /// Mitsuba).
    fn define(&mut self, node: &Node) -> Result<(), String> {
        let Some(id) = self.xml.attribute(node, "id")? else {
            return Ok(());
        };
        let definition = Definition {
            tag: node.tag_name().name().to_string(),
            kind: self.xml.attribute(node, "type")?.unwrap_or_default(),
            file: self.file,
            line: line(node),
        };
        if let Some(previous) = self.ids.get(&id) {
            if previous.file == definition.file && previous.line == definition.line {
                return Ok(());
            }
            return Err(format!(
                "line {}: duplicate id `{id}` (first given at {}:{})",
                definition.line,
                self.files[previous.file].0.display(),
                previous.line
            ));
        }
        self.ids.insert(id, definition);
        Ok(())
    }

    /// One element of the scene.
    fn element(&mut self, node: &Node) -> Result<(), String> {
        let at = line(node);
        match node.tag_name().name() {
            "default" | "path" | "include" => {}
            "integrator" => {
                self.integrator(node)?;
                if self.integrator.is_none() {
                    self.integrator_refused = true;
                }
            }
            "sensor" => self.sensor(node)?,
            "bsdf" => {
                let Some(id) = self.xml.attribute(node, "id")? else {
                    self.problem(at, "a top-level <bsdf> without `id` is never used");
                    return Ok(());
                };
                match self.bsdf(node)? {
                    Some(bsdf) => {
                        self.bsdfs.insert(id, bsdf);
                    }
                    None => {
                        self.refused_bsdfs.insert(id, (self.file, at));
                    }
                }
            }
            // Converted where a BSDF refers to it (`bsdf.rs`).
            "texture" if node.attribute("id").is_some() => {}
            "shape" => self.shape(node)?,
            "emitter" => self.emitter(node)?,
            other => self.problem(at, format!("<{other}> is not converted")),
        }
        Ok(())
    }

    /// What a reference to `id` names, for a message: "the <bsdf> (`plastic`) at FILE:LINE".
    fn what_is(&self, id: &str) -> String {
        match self.ids.get(id) {
            Some(d) => format!(
                "the <{}>{} at {}:{}",
                d.tag,
                if d.kind.is_empty() {
                    String::new()
                } else {
                    format!(" (`{}`)", d.kind)
                },
                self.files[d.file].0.display(),
                d.line
            ),
            None => "nothing: no element has that id".to_string(),
        }
    }

    /// The scene, with Mitsuba's defaults for the parts the XML does not give.
    fn description(&mut self, root: &Node) -> SceneDescription {
        let at = line(root);
        let camera = self.camera.clone().unwrap_or_else(|| {
            self.report.camera_missing = true;
            self.problem(
                at,
                "the scene has no convertible sensor (nothing is written, even with --partial)",
            );
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
            filter: sensor::default_filter(),
        });
        let sampler = self.sampler.take().unwrap_or(SamplerDescription {
            spp: sensor::DEFAULT_SPP,
            seed: 0,
            jitter: true,
        });
        let integrator = self.integrator.take().unwrap_or_else(|| {
            if self.integrator_refused {
                self.note(
                    at,
                    "the integrator was not converted (above): with --partial, lumis renders \
                     with `path`, Mitsuba's default",
                );
            } else {
                self.note(
                    at,
                    "no <integrator>: Mitsuba's default, `path`, becomes lumis `path` as a `path` \
                     element does",
                );
            }
            integrator::mitsuba_path()
        });
        if let Some((factor, at)) = self.delta_light_factor {
            self.scale_delta_lights(factor, at);
        }
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

    /// Multiplies the intensity of every delta light (point, spot, directional) by `factor`, or
    /// removes them at 0, as Mitsuba's `direct` (integrator at line `at`) renders them: its
    /// emitter samples of a delta light are weighted 1, not 1/`emitter_samples`
    /// (direct.cpp, `dr::select(ds.delta, 1, ...)`), and BSDF samples never reach one.
    fn scale_delta_lights(&mut self, factor: i64, at: u32) {
        let delta = [point::NAME, spot::NAME, directional::NAME];
        let is_delta = |e: &PluginSpec| delta.contains(&e.kind.as_str());
        let count = self.emitters.iter().filter(|e| is_delta(e)).count();
        if count == 0 {
            return;
        }
        if factor == 0 {
            self.emitters.retain(|e| !is_delta(e));
            self.note(
                at,
                format!(
                    "Mitsuba's `direct` without emitter samples never reaches a delta light: \
                     the scene's {count} point, spot or directional light(s) are left out, as in \
                     its image"
                ),
            );
            return;
        }
        for e in self.emitters.iter_mut().filter(|e| is_delta(e)) {
            let scale = match e.params.get(SCALE.name) {
                Some(ron::Value::Number(n)) => n.into_f64(),
                _ => 1.0,
            };
            e.params.insert(
                SCALE.name.into(),
                ron::Value::Number(ron::value::Number::from((scale * factor as f64) as f32)),
            );
        }
        self.note(
            at,
            format!(
                "Mitsuba's `direct` weights each of its {factor} emitter samples of a delta light \
                 by 1, not 1/{factor} (direct.cpp): its image has the scene's {count} point, spot \
                 or directional light(s) {factor} times as bright; their `scale` is multiplied by \
                 {factor} to render the same image (divide it by {factor} for the scene's \
                 physical light)"
            ),
        );
    }

    /// An asset file name in the XML, as the RON file must write it, found as Mitsuba finds
    /// it (the `<path>` folders, the main file's folder, then the folder of the file being
    /// read); `None`, after a problem at
    /// `at` naming what it is (`what`, e.g. "mesh file"), if no folder holds it.
    fn asset(&mut self, name: &str, at: u32, what: &str) -> Option<String> {
        // Mitsuba also looks beside an included file while it reads it.
        let mut places = self.search.clone();
        let here = files::parent(&self.files[self.file].0);
        if !places.contains(&here) {
            places.push(here);
        }
        match files::find(&places, name) {
            Some(found) => Some(paths::found_as_written(name, &found, &self.out_dir)),
            None => {
                let places: Vec<String> = places
                    .iter()
                    .map(|p| format!("`{}`", p.display()))
                    .collect();
                self.problem(
                    at,
                    format!(
                        "{what} `{name}` not found (looked in {})",
                        places.join(", ")
                    ),
                );
                None
            }
        }
    }
}
