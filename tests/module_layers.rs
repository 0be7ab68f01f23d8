//! The library crates' modules form layers: no module imports itself through others (an import
//! circle), the modules a plugin crate's plugins share import no plugin, and core's geometry
//! imports nothing from the scene file's parsing.
//!
//! Imports are read from the sources, not the compiler: `use` trees and paths written in code
//! that start with `crate::`, `super::`, `self::` or a child module's name, comments and string
//! literals left out, each resolved to the deepest module of the crate it names. A module's
//! `mod child;` declaration is not an import; a parent that uses or re-exports a child's item
//! imports that child. The circle check reads test code too (a circle through a test module
//! tangles the crate as much); the geometry check reads what the library builds.
//!
//! Tarjan's algorithm finds the strongly connected components of each crate's import graph: a
//! component of more than one module is a circle.
//!
//! Why one file of over 600 lines: the import reader (use trees, paths, inline modules, comments
//! and strings left out), Tarjan's algorithm and the checks, with tests of the reader itself.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::Path;

/// The library crates checked, by directory in the workspace.
const CHECKED_CRATES: [&str; 7] = [
    "core",
    "plugins/bsdfs",
    "plugins/emitters",
    "plugins/integrators",
    "plugins/textures",
    "plugins/examples/mis_methods",
    "plugins/examples/oren_nayar",
];

/// Workspace members not checked, and why: the root package's importer and study split one
/// module over files that use their parent's types (`super::`) while the parent uses theirs,
/// as does the Python binding's `study` with its crate root; `benches` has no `src/`.
const UNCHECKED_CRATES: [&str; 3] = [".", "python", "benches"];

/// A module's path below its crate's root: `[]` is the root, `["geometry", "bvh"]` is
/// `crate::geometry::bvh`.
type Module = Vec<String>;

/// Each module of a crate with the modules of the crate it imports.
type ImportGraph = BTreeMap<Module, BTreeSet<Module>>;

fn name(module: &[String]) -> String {
    std::iter::once("crate")
        .chain(module.iter().map(String::as_str))
        .collect::<Vec<_>>()
        .join("::")
}

/// Module `parent`'s child `child`.
fn child_of(parent: &[String], child: &str) -> Module {
    let mut module = parent.to_vec();
    module.push(child.to_string());
    module
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Every source file of the crate whose sources are in `src`, by module (`mod.rs`, `lib.rs` and
/// `main.rs` are their directory's module).
fn crate_sources(src: &Path) -> BTreeMap<Module, String> {
    let mut sources = BTreeMap::new();
    let mut directories = vec![src.to_path_buf()];
    while let Some(directory) = directories.pop() {
        let entries = std::fs::read_dir(&directory)
            .unwrap_or_else(|e| panic!("{}: {e}", directory.display()));
        for entry in entries {
            let path = entry.expect("a readable directory entry").path();
            if path.is_dir() {
                directories.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let relative = path.strip_prefix(src).expect("a file below src/");
            let mut module: Module = relative
                .with_extension("")
                .iter()
                .map(|part| part.to_str().expect("a UTF-8 file name").to_string())
                .collect();
            if matches!(
                module.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                module.pop();
            }
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            sources.insert(module, text);
        }
    }
    sources
}

fn starts_with_at(chars: &[char], at: usize, prefix: &str) -> bool {
    prefix
        .chars()
        .enumerate()
        .all(|(k, c)| chars.get(at + k) == Some(&c))
}

/// `text` without its comments and with every string and character literal emptied, so that
/// neither is read as code.
fn code_of(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let n = chars.len();
    let mut code = String::with_capacity(text.len());
    let mut i = 0;
    while i < n {
        let c = chars[i];
        let after_ident = |at: usize| at > 0 && is_ident(chars[at - 1]);
        if starts_with_at(&chars, i, "//") {
            while i < n && chars[i] != '\n' {
                i += 1;
            }
        } else if starts_with_at(&chars, i, "/*") {
            let mut depth = 0;
            while i < n {
                if starts_with_at(&chars, i, "/*") {
                    depth += 1;
                    i += 2;
                } else if starts_with_at(&chars, i, "*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if c == 'r'
            && (!after_ident(i) || (chars[i - 1] == 'b' && !after_ident(i - 1)))
            && chars[i + 1..].iter().find(|&&c| c != '#') == Some(&'"')
        {
            // A raw string, r"…" or r#"…"#: it ends at the quote followed by as many hashes.
            let hashes = chars[i + 1..].iter().take_while(|&&c| c == '#').count();
            let end: String = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            let mut j = i + hashes + 2;
            while j < n && !starts_with_at(&chars, j, &end) {
                j += 1;
            }
            code.push_str("\"\"");
            i = j + end.chars().count();
        } else if c == '"' {
            let mut j = i + 1;
            while j < n && chars[j] != '"' {
                j += if chars[j] == '\\' { 2 } else { 1 };
            }
            code.push_str("\"\"");
            i = j + 1;
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{1F600}'), or else a lifetime or label.
            let literal_end = if chars.get(i + 1) == Some(&'\\') {
                (i + 3..n.min(i + 12)).find(|&j| chars[j] == '\'')
            } else if chars.get(i + 2) == Some(&'\'') && chars[i + 1] != '\'' {
                Some(i + 2)
            } else {
                None
            };
            match literal_end {
                Some(end) => {
                    code.push_str("' '");
                    i = end + 1;
                }
                None => {
                    code.push(c);
                    i += 1;
                }
            }
        } else {
            code.push(c);
            i += 1;
        }
    }
    code
}

/// The length of the item `code` starts with: through its `;`, or its block's closing brace
/// when a `{` comes first.
fn item_len(code: &str) -> usize {
    match (code.find('{'), code.find(';')) {
        (brace, Some(semicolon)) if brace.is_none_or(|brace| semicolon < brace) => semicolon + 1,
        (Some(brace), _) => closing_brace(code, brace).map_or(code.len(), |close| close + 1),
        _ => code.len(),
    }
}

/// Where the brace opened at `open` closes.
fn closing_brace(code: &str, open: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (i, b) in code.bytes().enumerate().skip(open) {
        match b {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

const CFG_TEST: &str = "#[cfg(test)]";

/// `code` without its `#[cfg(test)]` items, and the modules those declare in files of their
/// own (`#[cfg(test)] mod tests;`).
fn without_test_code(code: &str) -> (String, Vec<String>) {
    let (mut kept, mut test_modules) = (String::new(), Vec::new());
    let mut rest = code;
    while let Some(at) = rest.find(CFG_TEST) {
        kept.push_str(&rest[..at]);
        let item = &rest[at + CFG_TEST.len()..];
        let len = item_len(item);
        let words: Vec<&str> = item[..len]
            .trim_end_matches(';')
            .split_whitespace()
            .collect();
        if item[..len].ends_with(';') && words.len() >= 2 && words[words.len() - 2] == "mod" {
            test_modules.push(words[words.len() - 1].to_string());
        }
        rest = &item[len..];
    }
    kept.push_str(rest);
    (kept, test_modules)
}

/// The paths a `use` tree names: `a::{b, c::{self, d as e}}` names `a::b`, `a::c::self` and
/// `a::c::d`.
fn use_paths(tree: &str, prefix: &str, paths: &mut Vec<String>) {
    let (mut depth, mut start, mut items) = (0, 0, Vec::new());
    for (i, c) in tree.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&tree[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&tree[start..]);
    for item in items.into_iter().map(str::trim).filter(|i| !i.is_empty()) {
        if let Some(open) = item.find('{') {
            let close = item.rfind('}').filter(|&c| c > open).unwrap_or(item.len());
            let head: String = item[..open].split_whitespace().collect();
            use_paths(&item[open + 1..close], &format!("{prefix}{head}"), paths);
        } else {
            let words: Vec<&str> = item.split_whitespace().collect();
            let alias = words.iter().position(|w| *w == "as").unwrap_or(words.len());
            paths.push(format!("{prefix}{}", words[..alias].concat()));
        }
    }
}

/// Where each word `keyword` followed by white space starts in `code`.
fn keyword_positions<'a>(code: &'a str, keyword: &'a str) -> impl Iterator<Item = usize> + 'a {
    code.match_indices(keyword)
        .map(|(at, _)| at)
        .filter(move |&at| {
            let before = code[..at].chars().next_back();
            let after = code[at + keyword.len()..].chars().next();
            before.is_none_or(|c| !is_ident(c) && c != ':')
                && after.is_some_and(char::is_whitespace)
        })
}

/// The crate module `path`, written in module `here` (a file's module, or an inline module
/// within it) of the file of module `file`, names, if it names one.
fn resolve(
    path: &str,
    here: &[String],
    file: &[String],
    modules: &BTreeSet<Module>,
) -> Option<Module> {
    if path.starts_with("::") {
        return None; // an external crate
    }
    let segments: Vec<&str> = path.split("::").collect();
    let (mut target, rest) = match segments[0] {
        "crate" => (Vec::new(), &segments[1..]),
        "super" | "self" => {
            let mut base = here.to_vec();
            let relative = segments
                .iter()
                .take_while(|s| matches!(**s, "super" | "self"))
                .count();
            for segment in &segments[..relative] {
                if *segment == "super" {
                    base.pop();
                }
            }
            (base, &segments[relative..])
        }
        child if here == file && modules.contains(&child_of(file, child)) => {
            (file.to_vec(), &segments[..])
        }
        _ => return None,
    };
    for segment in rest {
        let next = child_of(&target, segment);
        if !modules.contains(&next) {
            break;
        }
        target = next;
    }
    modules.contains(&target).then_some(target)
}

/// The crate modules the code of module `file` imports (itself left out), given every module
/// of the crate.
fn imports_of(file: &[String], code: &str, modules: &BTreeSet<Module>) -> BTreeSet<Module> {
    // Inline modules (`mod tests { … }`), in which `super` and `self` are relative to them.
    let inline: Vec<(usize, usize, &str)> = keyword_positions(code, "mod")
        .filter_map(|at| {
            let rest = code[at + 3..].trim_start();
            let ident_len = rest.find(|c: char| !is_ident(c)).unwrap_or(rest.len());
            let open = code.len() - rest[ident_len..].trim_start().len();
            (ident_len > 0 && code[open..].starts_with('{')).then(|| {
                let close = closing_brace(code, open).unwrap_or(code.len());
                (open, close, &rest[..ident_len])
            })
        })
        .collect();
    let scope = |at: usize| -> Module {
        let inner = inline
            .iter()
            .filter(|(open, close, _)| (*open..=*close).contains(&at));
        inner.fold(file.to_vec(), |scope, (_, _, m)| child_of(&scope, m))
    };
    let mut paths: Vec<(String, Module)> = Vec::new();
    let mut use_spans = Vec::new();
    for at in keyword_positions(code, "use") {
        let end = code[at..].find(';').map_or(code.len(), |e| at + e);
        let mut named = Vec::new();
        use_paths(&code[at + 3..end], "", &mut named);
        paths.extend(named.into_iter().map(|p| (p, scope(at))));
        use_spans.push(at..end);
    }
    // Paths written in code: `a::b::c` not preceded by an identifier or `::`.
    let bytes = code.as_bytes();
    let mut i = 0;
    while i < code.len() {
        let starts_path = code[i..].starts_with(is_ident)
            && code[..i]
                .chars()
                .next_back()
                .is_none_or(|c| !is_ident(c) && c != ':');
        if !starts_path {
            i += code[i..].chars().next().map_or(1, char::len_utf8);
            continue;
        }
        let mut end = i;
        loop {
            end += code[end..]
                .find(|c: char| !is_ident(c))
                .unwrap_or(code.len() - end);
            let continues = code[end..].starts_with("::")
                && code[end + 2..].starts_with(|c: char| is_ident(c) && !c.is_ascii_digit());
            if !continues {
                break;
            }
            end += 2;
        }
        if bytes[i..end].contains(&b':') && !use_spans.iter().any(|span| span.contains(&i)) {
            paths.push((code[i..end].to_string(), scope(i)));
        }
        i = end;
    }
    paths
        .iter()
        .filter_map(|(path, here)| resolve(path, here, file, modules))
        .filter(|target| target != file)
        .collect()
}

/// The import graph of a crate's `sources`; with `test_code`, the imports of `#[cfg(test)]`
/// code and test modules too.
fn import_graph(sources: &BTreeMap<Module, String>, test_code: bool) -> ImportGraph {
    let modules: BTreeSet<Module> = sources.keys().cloned().collect();
    let mut test_modules = BTreeSet::new();
    let mut codes = BTreeMap::new();
    for (module, text) in sources {
        let code = code_of(text);
        let code = if test_code {
            code
        } else {
            let (kept, declared) = without_test_code(&code);
            test_modules.extend(declared.iter().map(|m| child_of(module, m)));
            kept
        };
        codes.insert(module, code);
    }
    let under_test_module = |m: &Module| (1..=m.len()).any(|k| test_modules.contains(&m[..k]));
    codes
        .into_iter()
        .filter(|(module, _)| !under_test_module(module))
        .map(|(module, code)| {
            let imports = imports_of(module, &code, &modules)
                .into_iter()
                .filter(|m| !under_test_module(m))
                .collect();
            (module.clone(), imports)
        })
        .collect()
}

/// The graph's strongly connected components of more than one module (Tarjan 1972): each is a
/// set of modules that import one another, directly or through others.
fn circles(graph: &ImportGraph) -> Vec<BTreeSet<Module>> {
    struct Tarjan<'a> {
        graph: &'a ImportGraph,
        index: BTreeMap<&'a Module, usize>,
        low: BTreeMap<&'a Module, usize>,
        stack: Vec<&'a Module>,
        on_stack: BTreeSet<&'a Module>,
        components: Vec<BTreeSet<Module>>,
    }
    impl<'a> Tarjan<'a> {
        fn visit(&mut self, v: &'a Module) {
            let index = self.index.len();
            self.index.insert(v, index);
            self.low.insert(v, index);
            self.stack.push(v);
            self.on_stack.insert(v);
            for w in self.graph[v].iter().filter(|w| self.graph.contains_key(*w)) {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    self.low.insert(v, self.low[v].min(self.low[w]));
                } else if self.on_stack.contains(w) {
                    self.low.insert(v, self.low[v].min(self.index[w]));
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = BTreeSet::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack.remove(w);
                    component.insert(w.clone());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    self.components.push(component);
                }
            }
        }
    }
    let mut tarjan = Tarjan {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        components: Vec::new(),
    };
    for module in graph.keys() {
        if !tarjan.index.contains_key(module) {
            tarjan.visit(module);
        }
    }
    tarjan.components
}

/// One shortest circle through the first module of `component`, as `crate::a → crate::b →
/// crate::a`, for the failure's message.
fn describe(graph: &ImportGraph, component: &BTreeSet<Module>) -> String {
    let start = component.first().expect("a component has modules");
    let mut came_from: BTreeMap<&Module, &Module> = BTreeMap::new();
    let mut queue = VecDeque::from([start]);
    while let Some(m) = queue.pop_front() {
        for next in graph[m].iter().filter(|n| component.contains(*n)) {
            if next == start {
                let mut circle = vec![name(start), name(m)];
                let mut at = m;
                while at != start {
                    at = came_from[at];
                    circle.push(name(at));
                }
                circle.reverse();
                return circle.join(" → ");
            }
            if !came_from.contains_key(next) {
                came_from.insert(next, m);
                queue.push_back(next);
            }
        }
    }
    unreachable!("a strongly connected component has a circle through each of its modules")
}

fn workspace_path(relative: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// The circles of every checked crate, as messages (empty: none).
fn every_circle() -> Vec<String> {
    let mut found = Vec::new();
    for directory in CHECKED_CRATES {
        let graph = import_graph(&crate_sources(&workspace_path(directory).join("src")), true);
        for component in circles(&graph) {
            found.push(format!("{directory}: {}", describe(&graph, &component)));
        }
    }
    found
}

#[test]
fn no_module_of_a_library_crate_imports_itself_through_others() {
    let found = every_circle();
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
    // The scan reads the crates: core's and the integrators' modules import one another.
    for (directory, at_least) in [("core", 100), ("plugins/integrators", 100)] {
        let graph = import_graph(&crate_sources(&workspace_path(directory).join("src")), true);
        let imports: usize = graph.values().map(BTreeSet::len).sum();
        assert!(
            imports >= at_least,
            "{directory}: only {imports} imports found"
        );
    }
}

/// Every member of the workspace is checked or named as left out, with its reason.
#[test]
fn every_workspace_crate_is_checked_or_excused() {
    let manifest = std::fs::read_to_string(workspace_path("Cargo.toml")).expect("Cargo.toml");
    let members = manifest
        .lines()
        .find_map(|l| l.strip_prefix("members = ["))
        .expect("a one-line `members = [...]` in the workspace's Cargo.toml");
    let members: BTreeSet<&str> = members.split('"').skip(1).step_by(2).collect();
    let named: BTreeSet<&str> = CHECKED_CRATES
        .iter()
        .chain(&UNCHECKED_CRATES)
        .copied()
        .collect();
    let members_and_root: BTreeSet<&str> = members.into_iter().chain(["."]).collect();
    assert_eq!(
        members_and_root, named,
        "CHECKED_CRATES and UNCHECKED_CRATES"
    );
}

/// In a plugin crate, the modules that register no plugin (what the plugins share) import no
/// module that registers one: plugins build on the shared modules, never the reverse.
#[test]
fn shared_modules_of_a_plugin_crate_import_no_plugin() {
    let mut plugins_found = 0;
    for directory in CHECKED_CRATES {
        let sources = crate_sources(&workspace_path(directory).join("src"));
        let plugins: BTreeSet<&Module> = sources
            .iter()
            .filter(|(_, text)| code_of(text).contains("inventory::submit!"))
            .map(|(module, _)| module)
            .collect();
        plugins_found += plugins.len();
        for (module, imports) in import_graph(&sources, true) {
            if plugins.contains(&module) {
                continue;
            }
            if let Some(import) = imports.iter().find(|i| plugins.contains(i)) {
                panic!(
                    "{directory}: {}, shared by the plugins, imports the plugin {}",
                    name(&module),
                    name(import)
                );
            }
        }
    }
    assert!(
        plugins_found >= 20,
        "only {plugins_found} plugin modules found"
    );
}

/// Core's geometry, outside its tests, imports only itself and the numerical modules: nothing
/// of the scene file or its loading.
#[test]
fn core_geometry_imports_nothing_of_the_scene() {
    let graph = import_graph(&crate_sources(&workspace_path("core/src")), false);
    let geometry = |m: &Module| m.first().is_some_and(|top| top == "geometry");
    let allowed =
        |m: &Module| geometry(m) || ["math", "limits", "huge_pages"].contains(&m[0].as_str());
    let mut modules = 0;
    for (module, imports) in graph.iter().filter(|(m, _)| geometry(m)) {
        modules += 1;
        for import in imports {
            assert!(
                !import.is_empty() && allowed(import),
                "{} imports {}",
                name(module),
                name(import)
            );
        }
    }
    assert!(modules >= 10, "only {modules} geometry modules found");
}

fn synthetic(files: &[(&str, &str)]) -> BTreeMap<Module, String> {
    files
        .iter()
        .map(|(module, text)| {
            let path = module.split("::").filter(|s| !s.is_empty());
            (path.map(str::to_string).collect(), text.to_string())
        })
        .collect()
}

fn modules(names: &[&str]) -> BTreeSet<Module> {
    names
        .iter()
        .map(|n| {
            n.split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect()
        })
        .collect()
}

/// The scan finds `use` trees, paths in code (`crate::`, `super::`, a child's name), not
/// comments, strings or external crates, and resolves each to the deepest module it names.
#[test]
fn the_scan_reads_use_trees_and_paths_in_code() {
    let sources = synthetic(&[
        (
            "",
            "mod a;\nmod b;\nmod c;\nmod d;\nmod e;\npub use d::{Thing as Other, inner::{self}};",
        ),
        (
            "a",
            "use crate::{b::B, c::{self as see}};\n// crate::e::x\nfn f() { super::e::g(); }\nconst S: &str = \"crate::e\";\nfn h<'l>(c: &'l char) -> char { '\"' }",
        ),
        ("b", "use ::d::Foo;\nfn x() { let _ = d::bar(); }"),
        ("c", "mod tests {\n    use super::super::b;\n}"),
        ("d", "pub mod inner;"),
        ("d::inner", "use self::super::super::e as _;"),
        (
            "e",
            "#[cfg(test)]\nmod tests { use crate::a; }\n#[cfg(test)]\nmod more;",
        ),
        ("e::more", "use crate::b;"),
    ]);
    let graph = import_graph(&sources, true);
    let imports = |m: &str| graph[&modules(&[m]).pop_first().unwrap()].clone();
    assert_eq!(imports("a"), modules(&["b", "c", "e"]));
    assert_eq!(
        imports("b"),
        modules(&[]),
        "`::d` and `d::` name the external crate d"
    );
    assert_eq!(imports("c"), modules(&["b"]));
    assert_eq!(imports(""), modules(&["d", "d::inner"]));
    assert_eq!(imports("d::inner"), modules(&["e"]));
    assert_eq!(imports("e"), modules(&["a"]));
    assert_eq!(imports("e::more"), modules(&["b"]));
    // Without test code, `e`'s test module and its imports are gone.
    let graph = import_graph(&sources, false);
    assert_eq!(graph[&modules(&["e"]).pop_first().unwrap()], modules(&[]));
    assert!(!graph.contains_key(&modules(&["e::more"]).pop_first().unwrap()));
}

/// A circle is found and named, however long; layers are not circles.
#[test]
fn a_planted_circle_is_found() {
    let layered = synthetic(&[
        ("", "mod a;\nmod b;\nmod c;"),
        ("a", "use crate::b::X;"),
        ("b", "use crate::c::Y;"),
        ("c", ""),
    ]);
    assert!(circles(&import_graph(&layered, true)).is_empty());
    let circular = synthetic(&[
        ("", "mod a;\nmod b;\nmod c;\nmod d;"),
        ("a", "use crate::b::X;"),
        ("b", "use crate::c::Y;"),
        ("c", "fn f() { crate::a::g(); }"),
        ("d", "use crate::a::Z;"),
    ]);
    let graph = import_graph(&circular, true);
    let found = circles(&graph);
    assert_eq!(found, [modules(&["a", "b", "c"])]);
    assert_eq!(
        describe(&graph, &found[0]),
        "crate::a → crate::b → crate::c → crate::a"
    );
}
