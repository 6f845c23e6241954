//! The library's layers read top-down (ARCHITECTURE.md): every module uses
//! only modules of lower layers, or files of its own package that do not
//! form an import circle. Read from the `crate::` paths of every source file,
//! so that a new import that breaks the layering fails here.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level modules from the bottom layer up; a module may use only those
/// before it (and its own package).
const LAYERS: &[&[&str]] = &[
    &["num"],
    &["models"],
    &["plan"],
    &["backend"],
    &["reference"],
    &["scene"],
    &["output"],
    &["report", "verify", "bench"],
];

/// The source folders of the library's crates: the lower layers are crates
/// of their own (`crates/`, whose boundaries the compiler keeps too), read
/// here as one tree of modules.
fn roots() -> Vec<PathBuf> {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    ["", "crates/reeb-core", "crates/reeb-backend"]
        .iter()
        .map(|c| top.join(c).join("src"))
        .collect()
}

/// Every source file of the library's crates.
fn sources() -> Vec<PathBuf> {
    let mut files = vec![];
    for root in roots() {
        rust_files(&root, &mut files);
    }
    files
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Module path of a file: `src/plan/mod.rs` → [plan], `src/plan/scheme.rs` → [plan, scheme].
fn module_of(file: &Path) -> Vec<String> {
    let root = roots().into_iter().find(|r| file.starts_with(r));
    let rel = file.strip_prefix(root.expect("a source folder")).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|c| c.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if parts.last().is_some_and(|l| l == "mod" || l == "lib") {
        parts.pop();
    }
    parts
}

/// The code of a file without comments (doc examples name paths too) and
/// without its unit tests (whose `super::` is the file itself).
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .map(|l| match l.find("//") {
            Some(k) => &l[..k],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every `crate::a::b::…` path in the code, as its segments.
fn crate_paths(code: &str) -> Vec<Vec<String>> {
    let mut out = vec![];
    let mut rest = code;
    while let Some(k) = rest.find("crate::") {
        let before = rest[..k].chars().last();
        rest = &rest[k + 7..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let path: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
            .collect();
        let segs: Vec<String> = path
            .split("::")
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
        if !segs.is_empty() {
            out.push(segs);
        }
    }
    out
}

/// Exported macros live at the crate root (`crate::shared_fns!`): the module
/// of the file that defines each.
fn macro_homes(files: &[PathBuf]) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    for f in files {
        let text = std::fs::read_to_string(f).unwrap();
        for (k, _) in text.match_indices("macro_rules! ") {
            let name: String = text[k + 13..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            out.insert(name, module_of(f));
        }
    }
    out
}

/// `crate::…` paths of a file, with macro paths replaced by their home module.
fn uses(file: &Path, homes: &BTreeMap<String, Vec<String>>) -> Vec<Vec<String>> {
    crate_paths(&code(&std::fs::read_to_string(file).unwrap()))
        .into_iter()
        .map(|p| homes.get(&p[0]).cloned().unwrap_or(p))
        .collect()
}

/// The text with the bodies of `macro_rules!` definitions left out.
fn without_macros(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(k) = rest.find("macro_rules!") {
        out.push_str(&rest[..k]);
        let body = &rest[k..];
        let open = body.find('{').unwrap_or(body.len());
        let mut depth = 0;
        let mut end = body.len();
        for (i, c) in body[open..].char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + i + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        rest = &body[end..];
    }
    out.push_str(rest);
    out
}

fn layer(top: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&top))
}

#[test]
fn every_module_uses_only_lower_layers() {
    let files = sources();
    let homes = macro_homes(&files);
    let mut wrong = vec![];
    for f in &files {
        let module = module_of(f);
        let Some(own) = module.first().and_then(|t| layer(t)) else {
            continue; // lib.rs, main.rs: the top
        };
        for path in uses(f, &homes) {
            let top = &path[0];
            if *top == module[0] {
                continue;
            }
            match layer(top) {
                Some(l) if l < own => {}
                _ => wrong.push(format!(
                    "{} (layer {own}) uses crate::{}",
                    f.display(),
                    path.join("::")
                )),
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports against the layering:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_import_circle_between_files() {
    let files = sources();
    let homes = macro_homes(&files);
    let modules: BTreeMap<Vec<String>, &PathBuf> =
        files.iter().map(|f| (module_of(f), f)).collect();
    // The file a path lands in: its longest prefix that is a module.
    let resolve = |segs: &[String]| -> Option<Vec<String>> {
        (1..=segs.len())
            .rev()
            .map(|n| segs[..n].to_vec())
            .find(|m| modules.contains_key(m))
    };
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (m, f) in &modules {
        let text = code(&std::fs::read_to_string(f).unwrap());
        let mut targets: Vec<Vec<String>> = uses(f, &homes);
        // `use super::x` from a file is `crate::<parent>::x` (inside a macro
        // it is relative to where the macro expands: not this file's).
        for line in without_macros(&text).lines() {
            if let Some(k) = line.find("super::") {
                let path: String = line[k + 7..]
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                    .collect();
                let mut segs = m[..m.len().saturating_sub(1)].to_vec();
                segs.extend(path.split("::").filter(|s| !s.is_empty()).map(String::from));
                targets.push(segs);
            }
        }
        // Paths relative to the file's module: `child::x` (not `pub mod child;`).
        for child in modules
            .keys()
            .filter(|c| c.len() == m.len() + 1 && c.starts_with(m))
        {
            let name = format!("{}::", child[m.len()]);
            let used = text.match_indices(&name).any(|(k, _)| {
                !text[..k]
                    .chars()
                    .last()
                    .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
            });
            if used {
                targets.push(child.clone());
            }
        }
        for t in targets {
            if let Some(dst) = resolve(&t) {
                if dst != *m {
                    edges.entry(m.clone()).or_default().insert(dst);
                }
            }
        }
    }
    // Depth-first search for a back edge.
    fn visit(
        n: &Vec<String>,
        edges: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<String>> {
        state.insert(n.clone(), 1);
        stack.push(n.clone());
        for d in edges.get(n).into_iter().flatten() {
            match state.get(d) {
                Some(1) => {
                    let k = stack.iter().position(|s| s == d).unwrap();
                    let mut c: Vec<String> = stack[k..].iter().map(|s| s.join("::")).collect();
                    c.push(d.join("::"));
                    return Some(c);
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(d, edges, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(n.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in modules.keys() {
        if !state.contains_key(m) {
            let circle = visit(m, &edges, &mut state, &mut vec![]);
            assert!(
                circle.is_none(),
                "import circle: {}",
                circle.unwrap().join(" → ")
            );
        }
    }
}
