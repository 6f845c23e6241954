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
/// without the items compiled for tests alone (`#[cfg(test)]`: unit tests,
/// whose `super::` is the file itself, and test-only modules and helpers;
/// the code after such an item is read as any other).
fn code(text: &str) -> String {
    let text = text
        .lines()
        .map(|l| match l.find("//") {
            Some(k) => &l[..k],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = String::new();
    let mut rest = text.as_str();
    while let Some(k) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..k]);
        rest = &rest[k + "#[cfg(test)]".len()..];
        rest = &rest[item_len(rest)..];
    }
    out.push_str(rest);
    out
}

/// The length of the item `text` starts with: up to its `;` or the end of
/// its first braced block, whichever comes first.
fn item_len(text: &str) -> usize {
    let mut depth = 0;
    for (i, c) in text.char_indices() {
        match c {
            ';' if depth == 0 => return i + 1,
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
    }
    text.len()
}

/// Every `super::…` path in the code of module `m` that leaves the file,
/// as a path from the crate's root (`super::super::` climbs twice; inside
/// an inline `mod x { … }` the first climb is back to the file). Not inside
/// macros: there it is relative to where the macro expands.
fn super_paths(m: &[String], code: &str) -> Vec<Vec<String>> {
    let code = without_macros(code);
    let inline = inline_modules(&code);
    let mut out = vec![];
    for (k, _) in code.match_indices("super::") {
        let before = code[..k].chars().last();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            continue; // the second of `super::super::`, or `a::super::`
        }
        let mut rest = &code[k..];
        let mut up = 0usize;
        while let Some(r) = rest.strip_prefix("super::") {
            up += 1;
            rest = r;
        }
        let depth = inline.iter().filter(|r| r.contains(&k)).count();
        let Some(above) = up.checked_sub(depth).filter(|&a| a > 0) else {
            continue; // within the file
        };
        let path: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
            .collect();
        let mut segs = m[..m.len().saturating_sub(above)].to_vec();
        segs.extend(path.split("::").filter(|s| !s.is_empty()).map(String::from));
        out.push(segs);
    }
    out
}

/// Where the bodies of the inline modules (`mod x { … }`) of the code are.
fn inline_modules(code: &str) -> Vec<std::ops::Range<usize>> {
    let mut out = vec![];
    for (k, _) in code.match_indices("mod ") {
        if code[..k]
            .chars()
            .last()
            .is_some_and(|c| c.is_alphanumeric() || c == '_')
        {
            continue;
        }
        let after = &code[k + 4..];
        let name = after.trim_start();
        let ident = name
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .count();
        if ident == 0 || !name[ident..].trim_start().starts_with('{') {
            continue; // `mod x;`, or not a module
        }
        let open = k + 4 + (after.len() - name.len()) + ident;
        let open = open + code[open..].find('{').unwrap();
        out.push(open..open + item_len(&code[open..]));
    }
    out
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

/// `crate::…` paths of a file, with macro paths replaced by their home
/// module, and its `super::…` paths from the crate's root.
fn uses(file: &Path, homes: &BTreeMap<String, Vec<String>>) -> Vec<Vec<String>> {
    let code = code(&std::fs::read_to_string(file).unwrap());
    let crate_paths = crate_paths(&code)
        .into_iter()
        .map(|p| homes.get(&p[0]).cloned().unwrap_or(p));
    crate_paths
        .chain(super_paths(&module_of(file), &code))
        .filter(|p| !p.is_empty())
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
        // `use super::x` from a file is `crate::<parent>::x` (in `uses`).
        let mut targets: Vec<Vec<String>> = uses(f, &homes);
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

/// The reader of the two tests above: it reads the code after an item for
/// tests alone (not only up to the first), leaves test modules out, and
/// follows `super::` as far up as it climbs.
#[test]
fn the_import_reader_sees_past_test_items_and_follows_super() {
    let text = "#[cfg(test)]\nmod generator;\nuse crate::scene::Scene; // crate::output\n\
                #[cfg(test)]\nmod tests {\n    use super::*;\n    use crate::output::Run;\n}\n\
                use super::super::report::Table;\nfn f() { super::g() }\n\
                mod wide {\n    use super::*;\n    use super::super::h;\n}\n";
    let code = code(text);
    let path = |s: &[&str]| s.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    assert_eq!(crate_paths(&code), vec![path(&["scene", "Scene"])]);
    let m = path(&["backend", "cpu", "stops"]);
    assert_eq!(
        super_paths(&m, &code),
        vec![
            path(&["backend", "report", "Table"]),
            path(&["backend", "cpu", "g"]),
            path(&["backend", "cpu", "h"])
        ]
    );
}
