//! The layout rules ARCHITECTURE.md states, checked so that they do not drift: dependencies
//! between the crates pointing down the layers only (`LAYERS`), no import circle between the
//! modules of any crate, and `evigrid run` kept as wiring (`run.rs` at most 300 lines, no
//! function of the command-line crate over 150).
//!
//! Modules are read from the source files (`lib.rs`/`main.rs` the root, `mod.rs` its folder,
//! `a/b.rs` module `a::b`); an import is a `crate::…` or `super::…` path outside `#[cfg(test)]`
//! code. An import between two modules counts between their ancestors just below the lowest
//! common one (siblings), so `a::x → b::y` is `a → b`; a module's imports of its own ancestors
//! or descendants are not circles.

#![allow(clippy::unwrap_used)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

type Module = Vec<String>;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn module_of(src: &Path, file: &Path) -> Module {
    let relative = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Module = relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("lib" | "main" | "mod")
    ) {
        parts.pop();
    }
    parts
}

/// The code of a file without its tests and comments.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or_default();
    text.lines()
        .map(|line| line.split("//").next().unwrap_or_default())
        .collect::<Vec<_>>()
        .join("\n")
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The module paths a file names after `crate::` or `super::` (with `{a, b::c}` groups
/// expanded to each item's first segment), as paths from the crate root.
fn named_paths(module: &Module, code: &str) -> Vec<Module> {
    let mut found = Vec::new();
    for head in ["crate::", "super::"] {
        for (at, _) in code.match_indices(head) {
            if code[..at].chars().next_back().is_some_and(is_ident) {
                continue;
            }
            let mut base: Module = match head {
                "crate::" => Vec::new(),
                _ => module[..module.len().saturating_sub(1)].to_vec(),
            };
            let rest = &code[at + head.len()..];
            let path: String = rest
                .chars()
                .take_while(|&c| is_ident(c) || c == ':')
                .collect();
            base.extend(
                path.split("::")
                    .filter(|s| !s.is_empty())
                    .map(str::to_string),
            );
            // `path::{a, b::c}`: each item's first segment under the path.
            match rest[path.len()..].strip_prefix('{') {
                Some(group) => {
                    let group = group.split('}').next().unwrap_or_default();
                    for item in group.split(',') {
                        let first = item.trim().split("::").next().unwrap_or_default().trim();
                        if !first.is_empty() {
                            let mut named = base.clone();
                            named.push(first.to_string());
                            found.push(named);
                        }
                    }
                }
                None => found.push(base),
            }
        }
    }
    found
}

/// The import edges between sibling modules of one crate's source folder.
fn sibling_imports(src: &Path) -> BTreeSet<(Module, Module)> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeMap<Module, PathBuf> = files
        .iter()
        .map(|f| (module_of(src, f), f.clone()))
        .collect();
    let mut edges = BTreeSet::new();
    for (module, file) in &modules {
        if module.last().is_some_and(|m| m == "tests") {
            continue;
        }
        let code = code(&std::fs::read_to_string(file).unwrap());
        for mut target in named_paths(module, &code) {
            while !target.is_empty() && !modules.contains_key(&target) {
                target.pop();
            }
            let common = module
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            if common == module.len() || common == target.len() {
                continue; // itself, an ancestor or a descendant
            }
            edges.insert((module[..=common].to_vec(), target[..=common].to_vec()));
        }
    }
    edges
}

/// The modules on a circle of `edges`, if any: the first found.
fn circle(edges: &BTreeSet<(Module, Module)>) -> Option<Vec<Module>> {
    let mut next: BTreeMap<&Module, Vec<&Module>> = BTreeMap::new();
    for (a, b) in edges {
        next.entry(a).or_default().push(b);
    }
    // Depth-first search with the path on a stack; a node on the path seen again closes a
    // circle.
    fn visit<'a>(
        node: &'a Module,
        next: &BTreeMap<&'a Module, Vec<&'a Module>>,
        path: &mut Vec<&'a Module>,
        done: &mut BTreeSet<&'a Module>,
    ) -> Option<Vec<Module>> {
        if let Some(at) = path.iter().position(|m| *m == node) {
            return Some(path[at..].iter().map(|m| (*m).clone()).collect());
        }
        if !done.insert(node) {
            return None;
        }
        path.push(node);
        for &to in next.get(node).into_iter().flatten() {
            if let Some(found) = visit(to, next, path, done) {
                return Some(found);
            }
        }
        path.pop();
        None
    }
    let mut done = BTreeSet::new();
    for &start in next.keys() {
        let mut path = Vec::new();
        if let Some(found) = visit(start, &next, &mut path, &mut done) {
            return Some(found);
        }
    }
    None
}

#[test]
fn no_crate_has_an_import_circle_between_its_modules() {
    let mut circles = Vec::new();
    for entry in std::fs::read_dir(workspace().join("crates")).unwrap() {
        let src = entry.unwrap().path().join("src");
        if !src.is_dir() {
            continue;
        }
        if let Some(found) = circle(&sibling_imports(&src)) {
            let names: Vec<String> = found.iter().map(|m| m.join("::")).collect();
            circles.push(format!("{}: {}", src.display(), names.join(" → ")));
        }
    }
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
}

#[test]
fn the_checker_finds_a_circle_between_two_siblings() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path();
    std::fs::create_dir_all(src.join("motion")).unwrap();
    std::fs::write(src.join("lib.rs"), "mod motion;\n").unwrap();
    std::fs::write(src.join("motion/mod.rs"), "mod evidence;\nmod tracks;\n").unwrap();
    std::fs::write(
        src.join("motion/evidence.rs"),
        "use super::tracks::Track;\n",
    )
    .unwrap();
    std::fs::write(
        src.join("motion/tracks.rs"),
        "use crate::motion::{evidence, kalman};\n#[cfg(test)]\nmod tests { use super::*; }\n",
    )
    .unwrap();
    let edges = sibling_imports(src);
    let found = circle(&edges).unwrap();
    assert_eq!(found.len(), 2);
    // Without the back edge there is none; a parent and its child are no circle.
    std::fs::write(src.join("motion/tracks.rs"), "use super::Stage;\n").unwrap();
    assert!(circle(&sibling_imports(src)).is_none());
}

/// Items longer than `max_lines` in `file`: `fn` items from their line to the closing brace at
/// their indentation.
fn long_functions(file: &Path, max_lines: usize) -> Vec<String> {
    let text = std::fs::read_to_string(file).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let mut long = Vec::new();
    for (start, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let signature = trimmed
            .strip_prefix("pub(crate) ")
            .or_else(|| trimmed.strip_prefix("pub "))
            .unwrap_or(trimmed);
        let Some(rest) = signature.strip_prefix("fn ") else {
            continue;
        };
        if line.trim_end().ends_with(';') {
            continue;
        }
        let close = format!("{indent}}}");
        let end = lines[start..]
            .iter()
            .position(|l| *l == close)
            .map_or(lines.len(), |n| start + n);
        let length = end - start + 1;
        if length > max_lines {
            let name: String = rest.chars().take_while(|&c| is_ident(c)).collect();
            long.push(format!("{}: {name} is {length} lines", file.display()));
        }
    }
    long
}

#[test]
fn the_run_command_is_wiring() {
    let src = workspace().join("crates/cli/src");
    let run = std::fs::read_to_string(src.join("commands/run.rs")).unwrap();
    let lines = run.lines().count();
    assert!(
        lines <= 300,
        "commands/run.rs is {lines} lines (at most 300)"
    );
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let long: Vec<String> = files.iter().flat_map(|f| long_functions(f, 150)).collect();
    assert!(
        long.is_empty(),
        "functions over 150 lines:\n{}",
        long.join("\n")
    );
}

#[test]
fn the_length_check_measures_a_function_to_its_closing_brace() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("f.rs");
    let body = "    let x = 1;\n".repeat(3);
    std::fs::write(&file, format!("pub fn five() {{\n{body}}}\nfn one();\n")).unwrap();
    assert_eq!(long_functions(&file, 5), Vec::<String>::new());
    assert_eq!(long_functions(&file, 4).len(), 1);
}

/// The layers of ARCHITECTURE.md, bottom first: a crate may depend only on crates of a lower
/// layer (so none of the input crates on another, and `bench` on `session` and `output` but not
/// on `cli`). Folder names under `crates/`.
const LAYERS: [&[&str]; 6] = [
    &["belief", "geodata", "drive", "ground", "odometry"],
    &["evigrid"],
    &["output", "sim"],
    &["eval", "session"],
    &["bench", "fuzz"],
    &["cli", "python"],
];

fn layer_of(folder: &str) -> Option<usize> {
    LAYERS.iter().position(|layer| layer.contains(&folder))
}

/// The workspace's own crates a manifest's `[dependencies]` and `[build-dependencies]` name, as
/// folders under `crates/`; `folder_of` maps a dependency's key to its folder.
fn workspace_dependencies(manifest: &str, folder_of: &BTreeMap<String, String>) -> Vec<String> {
    let mut section = "";
    let mut found = Vec::new();
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            section = line;
            continue;
        }
        if section != "[dependencies]" && section != "[build-dependencies]" {
            continue;
        }
        let key = line.split(['=', '.']).next().unwrap_or_default().trim();
        if let Some(folder) = folder_of.get(key) {
            found.push(folder.clone());
        }
    }
    found
}

/// Each `crate → dependency` edge that does not point to a lower layer, or names a crate of no
/// layer.
fn layering_violations(edges: &[(String, String)]) -> Vec<String> {
    edges
        .iter()
        .filter(|(from, to)| match (layer_of(from), layer_of(to)) {
            (Some(from), Some(to)) => to >= from,
            _ => true,
        })
        .map(|(from, to)| format!("{from} → {to}"))
        .collect()
}

#[test]
fn crate_dependencies_point_down_the_layers() {
    let root = std::fs::read_to_string(workspace().join("Cargo.toml")).unwrap();
    let folder_of: BTreeMap<String, String> = root
        .lines()
        .filter_map(|line| {
            let (key, rest) = line.split_once('=')?;
            let path = rest.split("path = \"crates/").nth(1)?;
            let folder = path.split('"').next()?;
            Some((key.trim().to_string(), folder.to_string()))
        })
        .collect();
    assert!(folder_of.len() >= 10, "workspace dependencies not found");
    let mut edges = Vec::new();
    for entry in std::fs::read_dir(workspace().join("crates")).unwrap() {
        let dir = entry.unwrap().path();
        let Ok(manifest) = std::fs::read_to_string(dir.join("Cargo.toml")) else {
            continue;
        };
        let folder = dir.file_name().unwrap().to_string_lossy().into_owned();
        for dependency in workspace_dependencies(&manifest, &folder_of) {
            edges.push((folder.clone(), dependency));
        }
    }
    assert!(
        edges
            .iter()
            .any(|(from, to)| from == "bench" && to == "session"),
        "the reader missed bench → session: {edges:?}"
    );
    let wrong = layering_violations(&edges);
    assert!(
        wrong.is_empty(),
        "dependencies that do not point down:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn the_layering_check_refuses_an_upward_or_sideways_edge() {
    let folder_of: BTreeMap<String, String> = [("evigrid-bench", "bench"), ("session", "session")]
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .into_iter()
        .collect();
    let manifest = "[dependencies]\nsession = { workspace = true }\nserde.workspace = true\n\
                    [dev-dependencies]\nevigrid-bench.workspace = true\n";
    assert_eq!(workspace_dependencies(manifest, &folder_of), ["session"]);
    let edge = |from: &str, to: &str| (from.to_string(), to.to_string());
    assert!(layering_violations(&[edge("bench", "session"), edge("evigrid", "belief")]).is_empty());
    assert_eq!(
        layering_violations(&[
            edge("session", "bench"),
            edge("drive", "odometry"),
            edge("new", "evigrid"),
        ]),
        ["session → bench", "drive → odometry", "new → evigrid"]
    );
}
