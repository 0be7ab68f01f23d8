//! The XML files of a scene: the main file and those it includes, read as Mitsuba 3's parser
//! reads them (`src/core/parser.cpp`), with the `<default>` parameters, the `<path>` folders
//! and each file's format version.
//!
//! - `<include filename="...">` at the scene's level: the file is looked for in the including
//!   file's folder, then as an asset is (below); its root `<scene>`'s children take the
//!   include's place (another root element is taken as one element of the scene). An include
//!   that leads back to a file on its own chain is refused with the chain, as is a chain deeper
//!   than Mitsuba's limit of 15.
//! - `<path value="...">` (children of the main file's root only, as in Mitsuba): a folder,
//!   relative to the XML file's or absolute, searched for assets before those given earlier and
//!   the scene's folder. Mitsuba forgets the folders an included file adds once it is read, and
//!   so does this reader. The working directory, Mitsuba's last resort, is not searched: a scene
//!   converts the same from anywhere.
//! - `<default name value>`: parameters for `$name`; `-D` overrides come first, then the main
//!   file's, then each included file's for names not yet defined (as Mitsuba).

use super::properties::line;
use roxmltree::{Document, Node};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Mitsuba's `max_include_depth`.
pub(super) const MAX_INCLUDE_DEPTH: usize = 15;

/// Bytes of XML read in all (the main file and its includes), as a bound on what a scene made
/// of includes can make the reader hold.
pub(super) const MAX_XML_BYTES: usize = 1 << 30;

/// A file's `version` attribute.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Version(pub u32, pub u32, pub u32);

impl Version {
    /// Before Mitsuba 2: property names in camelCase, upgraded as Mitsuba 3 reads them.
    pub fn is_legacy(self) -> bool {
        self < Version(2, 0, 0)
    }

    /// A `version` attribute's value (`3.0` is 3.0.0); `None` if it is not one.
    pub fn parse(text: &str) -> Option<Version> {
        let mut parts = text.trim().split('.').map(|p| p.parse::<u32>().ok());
        let major = parts.next()??;
        let minor = parts.next().unwrap_or(Some(0))?;
        let patch = parts.next().unwrap_or(Some(0))?;
        parts
            .next()
            .is_none()
            .then_some(Version(major, minor, patch))
    }
}

impl std::fmt::Display for Version {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}.{}", self.0, self.1, self.2)
    }
}

/// One XML file of the scene.
pub(super) struct SourceFile {
    pub path: PathBuf,
    pub text: String,
    pub version: Version,
}

/// The scene's files, read and checked.
pub(super) struct Sources {
    /// The main file first.
    pub files: Vec<SourceFile>,
    /// (file, byte offset of an `<include>` element in it) → the file it includes.
    pub includes: HashMap<(usize, usize), usize>,
    /// `$name` parameters.
    pub parameters: BTreeMap<String, String>,
    /// Folders searched for assets, first first: the main file's `<path>` folders, the last
    /// given first, then the main file's folder.
    pub search: Vec<PathBuf>,
}

impl Sources {
    /// Reads the main file's `text` (at `path`) and every file it includes. Fails, naming the
    /// file and line, on malformed XML, a missing version, a missing file or folder, an include
    /// cycle or a chain too deep.
    pub fn read(
        path: &Path,
        text: String,
        defines: &[(String, String)],
    ) -> Result<Sources, String> {
        let mut sources = Sources {
            files: Vec::new(),
            includes: HashMap::new(),
            parameters: defines.iter().cloned().collect(),
            search: vec![parent(path)],
        };
        let mut budget = MAX_XML_BYTES;
        sources.add(path.to_path_buf(), text, &mut Vec::new(), &mut budget)?;
        let docs = sources
            .files
            .iter()
            .map(|f| Document::parse(&f.text))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("not valid XML: {e}"))?;
        let mut known: BTreeMap<String, String> = defines.iter().cloned().collect();
        sources.in_order(&docs, 0, docs[0].root_element(), &mut known)?;
        Ok(sources)
    }

    /// Checks that every `$name` in file `index` (from `node` down) is defined before it is
    /// used, in the order Mitsuba's parser reads the files: depth first through the elements,
    /// an included file where its `<include>` is, a `<default>` taking effect where it is (and
    /// for the rest of the scene, the including files too). `known` holds the parameters
    /// defined so far. Mitsuba fails on a parameter that a `<default>` defines only later
    /// ("undefined parameter"); so does this, naming where it is defined.
    fn in_order(
        &self,
        docs: &[Document],
        index: usize,
        node: Node,
        known: &mut BTreeMap<String, String>,
    ) -> Result<(), String> {
        let path = &self.files[index].path;
        for attribute in node.attributes() {
            if let Err(e) = substitute(attribute.value(), known) {
                let later = self
                    .parameters
                    .keys()
                    .filter(|n| !known.contains_key(*n))
                    .find(|n| attribute.value().contains(&format!("${n}")));
                return Err(match later {
                    Some(name) => format!(
                        "{}:{}: `${name}` is used before the <default> that defines it: Mitsuba \
                         reads parameters in order and refuses this (\"undefined parameter\"); \
                         give it with -D {name}=...",
                        path.display(),
                        line(&node)
                    ),
                    None => format!("{}:{}: {e}", path.display(), line(&node)),
                });
            }
        }
        match node.tag_name().name() {
            "default" => {
                if let (Some(name), Some(value)) = (node.attribute("name"), node.attribute("value"))
                {
                    known
                        .entry(name.to_string())
                        .or_insert_with(|| value.to_string());
                }
            }
            "include" => {
                if let Some(&child) = self.includes.get(&(index, node.range().start)) {
                    self.in_order(docs, child, docs[child].root_element(), known)?;
                }
            }
            _ => {}
        }
        for child in node.children().filter(Node::is_element) {
            self.in_order(docs, index, child, known)?;
        }
        Ok(())
    }

    /// Adds file `path` (text `text`) and, depth first, the files it includes; `chain` holds
    /// the files being read that include it. Returns its index.
    fn add(
        &mut self,
        path: PathBuf,
        text: String,
        chain: &mut Vec<PathBuf>,
        budget: &mut usize,
    ) -> Result<usize, String> {
        let at = |line: u32| format!("{}:{line}", path.display());
        let doc = Document::parse(&text)
            .map_err(|e| format!("{}: not valid XML: {e}", path.display()))?;
        let root = doc.root_element();
        let version = match root.attribute("version") {
            Some(v) => Version::parse(v)
                .ok_or_else(|| format!("{}: invalid version number `{v}`", at(line(&root))))?,
            None => {
                return Err(format!(
                    "{}: the root element <{}> has no `version` (Mitsuba requires one)",
                    at(line(&root)),
                    root.tag_name().name()
                ));
            }
        };
        let main = self.files.is_empty();
        // Defaults first (Mitsuba reads them as it meets them; every file here uses its own
        // and the earlier files').
        for node in root.children().filter(Node::is_element) {
            if node.tag_name().name() == "default" {
                let (Some(name), Some(value)) = (node.attribute("name"), node.attribute("value"))
                else {
                    return Err(format!(
                        "{}: <default> needs `name` and `value`",
                        at(line(&node))
                    ));
                };
                if name.is_empty() {
                    return Err(format!("{}: <default> needs a name", at(line(&node))));
                }
                self.parameters
                    .entry(name.to_string())
                    .or_insert_with(|| value.to_string());
            }
        }
        let index = self.files.len();
        let mut search = self.search.clone();
        let mut included = Vec::new();
        for node in root.children().filter(Node::is_element) {
            match node.tag_name().name() {
                "path" => {
                    let value = self.substitute(&node, "value", &path)?;
                    let mut folder = PathBuf::from(&value);
                    if folder.is_relative() {
                        let beside = parent(&path).join(&folder);
                        folder = if beside.is_dir() {
                            beside
                        } else {
                            find(&search, &value).unwrap_or(beside)
                        };
                    }
                    if !folder.is_dir() {
                        return Err(format!(
                            "{}: <path>: folder `{}` not found",
                            at(line(&node)),
                            folder.display()
                        ));
                    }
                    search.insert(0, folder);
                }
                "include" => {
                    let name = self.substitute(&node, "filename", &path)?;
                    let mut places = vec![parent(&path)];
                    places.extend(search.iter().cloned());
                    let Some(file) = find(&places, &name) else {
                        return Err(format!(
                            "{}: included file `{name}` not found (looked in {})",
                            at(line(&node)),
                            places
                                .iter()
                                .map(|p| format!("`{}`", p.display()))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ));
                    };
                    included.push((node.range().start, line(&node), file));
                }
                _ => {}
            }
        }
        // The main file's folders stay for the assets of every file; an included file's go
        // with it.
        if main {
            self.search = search;
        }
        self.files.push(SourceFile {
            path: path.clone(),
            text: String::new(),
            version,
        });
        drop(doc);
        *budget = budget.checked_sub(text.len()).ok_or_else(|| {
            format!(
                "{}: the scene's XML files add up to more than {MAX_XML_BYTES} bytes",
                path.display()
            )
        })?;
        self.files[index].text = text;
        chain.push(path.clone());
        for (offset, at_line, file) in included {
            let key = canonical(&file);
            if let Some(start) = chain.iter().position(|p| canonical(p) == key) {
                let names: Vec<String> = chain[start..]
                    .iter()
                    .chain([&file])
                    .map(|p| format!("`{}`", p.display()))
                    .collect();
                return Err(format!(
                    "{}: <include> makes a cycle: {}",
                    at(at_line),
                    names.join(" includes ")
                ));
            }
            if chain.len() >= MAX_INCLUDE_DEPTH {
                return Err(format!(
                    "{}: includes nested more than {MAX_INCLUDE_DEPTH} deep (Mitsuba's limit)",
                    at(at_line)
                ));
            }
            let text = std::fs::read_to_string(&file).map_err(|e| {
                format!(
                    "{}: cannot read included file `{}`: {e}",
                    at(at_line),
                    file.display()
                )
            })?;
            let child = self.add(file, text, chain, budget)?;
            self.includes.insert((index, offset), child);
        }
        chain.pop();
        Ok(index)
    }

    /// Attribute `name` of `node` (required), with `$` parameters substituted.
    fn substitute(&self, node: &Node, name: &str, path: &Path) -> Result<String, String> {
        let raw = node.attribute(name).ok_or_else(|| {
            format!(
                "{}:{}: <{}> needs `{name}`",
                path.display(),
                line(node),
                node.tag_name().name()
            )
        })?;
        substitute(raw, &self.parameters)
            .map_err(|e| format!("{}:{}: {e}", path.display(), line(node)))
    }
}

/// `raw` with `$name` parameters substituted, the longest names first (so that `$spp` does not
/// eat into `$spp2`); a `$` left over is an undefined parameter. `\$` is a literal `$`, as in
/// Mitsuba 3 (measured on 3.9.1: `x\$a` reads `x$a` with `a` defined, and `x\\$a` reads
/// `x\$a`: only the backslash before a `$` is an escape).
pub fn substitute(raw: &str, parameters: &BTreeMap<String, String>) -> Result<String, String> {
    if !raw.contains('$') {
        return Ok(raw.to_string());
    }
    let mut names: Vec<&String> = parameters.keys().collect();
    names.sort_by_key(|n| std::cmp::Reverse(n.len()));
    let mut pieces = Vec::new();
    for piece in raw.split("\\$") {
        let mut value = piece.to_string();
        for n in &names {
            value = value.replace(&format!("${n}"), &parameters[*n]);
        }
        if let Some(at) = value.find('$') {
            let name: String = value[at + 1..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            return Err(format!(
                "`{raw}` uses ${name}, which no <default> or -D defines (`\\$` is a literal `$`)"
            ));
        }
        pieces.push(value);
    }
    Ok(pieces.join("$"))
}

/// The folder of `path` (`.` for a bare file name).
pub(super) fn parent(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `name` if absolute and present, else the first of `places` joined with it that exists.
pub(super) fn find(places: &[PathBuf], name: &str) -> Option<PathBuf> {
    let path = Path::new(name);
    if path.is_absolute() {
        return path.exists().then(|| path.to_path_buf());
    }
    places.iter().map(|p| p.join(path)).find(|p| p.exists())
}

/// A path for comparing files (the same file reached by two names compares equal when the file
/// system can say so).
fn canonical(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}
