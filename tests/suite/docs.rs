//! The documentation's generated pages are what reeb itself says, so they
//! cannot drift: the command-line reference is every command's own help
//! (clap's), the citation page's tables are `summary.json`'s `references`
//! for every scheme and built-in model, the scene reference's key tables
//! are the parser's own, the outputs page's table of arrays is what reeb
//! writes (names, dimensions, element types), and the site's home page is
//! the README. After a change, `REEB_UPDATE_DOCS=1 cargo test --release
//! --test suite docs::` rewrites them.

use std::path::Path;

use reeb::models::MODEL_NAMES;
use reeb::output::references::references;
use reeb::plan::scheme::SCHEME_NAMES;

use crate::common::runs::ok;

const UPDATE: &str = "REEB_UPDATE_DOCS";

/// Checks that the text of `file` (under the repository) between the
/// markers `<!-- begin generated: NAME -->` and `<!-- end generated: NAME -->`
/// is `generated`, or rewrites it there under `REEB_UPDATE_DOCS=1`.
fn generated(file: &str, name: &str, generated: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    let (begin, end) = (
        format!("<!-- begin generated: {name} -->\n"),
        format!("<!-- end generated: {name} -->"),
    );
    let from = text.find(&begin).map(|k| k + begin.len());
    let to = text.find(&end);
    let (Some(from), Some(to)) = (from, to) else {
        panic!("{file} has no markers `{}` … `{end}`", begin.trim_end());
    };
    if std::env::var(UPDATE).as_deref() == Ok("1") {
        let new = format!("{}{generated}{}", &text[..from], &text[to..]);
        std::fs::write(&path, new).unwrap();
        return;
    }
    assert!(
        text[from..to] == *generated,
        "{file}'s generated part `{name}` is not what reeb says now: run `{UPDATE}=1 cargo test --release --test suite docs::` and commit the change"
    );
}

/// `reeb help ARGS…`, with a code block per command and subcommand.
fn help_of(path: &[&str], out: &mut String) {
    let mut args = vec!["help"];
    args.extend_from_slice(path);
    let text = ok(&args);
    let title = std::iter::once("reeb").chain(path.iter().copied());
    out.push_str(&format!(
        "\n## {}\n\n```text\n{}\n```\n",
        title.collect::<Vec<_>>().join(" "),
        text.trim_end()
    ));
    for sub in subcommands(&text) {
        let mut deeper = path.to_vec();
        deeper.push(&sub);
        help_of(&deeper, out);
    }
}

/// The subcommands a help text lists (clap's `Commands:` section), `help` aside.
fn subcommands(help: &str) -> Vec<String> {
    let Some(k) = help.find("\nCommands:\n") else {
        return vec![];
    };
    help[k + "\nCommands:\n".len()..]
        .lines()
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(String::from)
        .collect()
}

#[test]
fn the_command_line_reference_is_every_commands_own_help() {
    let mut text = String::new();
    help_of(&[], &mut text);
    assert!(text.contains("\n## reeb run\n") && text.contains("\n## reeb report stability\n"));
    generated("docs/cli.md", "help", &text);
}

#[test]
fn the_sites_home_page_is_the_readme() {
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md"));
    // The README's links, from the repository's root, as the site's pages
    // (under docs/) reach the same files.
    let home = readme
        .unwrap()
        .replace("](docs/", "](")
        .replace("src=\"docs/img/", "src=\"img/")
        .replace(
            "](python/examples/chaos_maps.ipynb)",
            "](tutorials/chaos-maps.ipynb)",
        );
    generated("docs/index.md", "readme", &home);
}

#[test]
fn the_citation_page_lists_the_papers_of_every_scheme_and_model() {
    // Every paper, numbered in the order the tables first cite it.
    let mut papers: Vec<&str> = vec![];
    let mut numbers = |cited: Vec<&'static str>| -> String {
        let each: Vec<String> = cited
            .into_iter()
            .map(|p| {
                if !papers.contains(&p) {
                    papers.push(p);
                }
                let k = papers.iter().position(|q| *q == p).unwrap() + 1;
                // A link to the paper below (a bare `[1]` reads as a link
                // reference to the site's cross-referencing).
                format!("[[{k}]](#paper-{k})")
            })
            .collect();
        match each.is_empty() {
            true => "—".into(),
            false => each.join(" "),
        }
    };
    let mut text = String::from("\n| scheme | papers |\n|---|---|\n");
    for scheme in SCHEME_NAMES {
        // A formula model cites nothing of its own: the scheme's papers alone.
        let cited = numbers(references(scheme, "a formula model"));
        text.push_str(&format!("| `{scheme}` | {cited} |\n"));
    }
    text.push_str("\n| model | papers |\n|---|---|\n");
    for model in MODEL_NAMES {
        let cited = numbers(references("rk4", model));
        text.push_str(&format!("| `{model}` | {cited} |\n"));
    }
    text.push('\n');
    for (k, p) in papers.iter().enumerate() {
        text.push_str(&format!("{0}. <a id=\"paper-{0}\"></a>{p}\n", k + 1));
    }
    text.push('\n');
    generated("docs/cite.md", "references", &text);
}

/// The scene every `bad` example is set in: the least a scene needs.
const BASE: &[(&str, &str)] = &[
    ("", "model = \"van_der_pol\""),
    ("integrator", "dt = 0.01"),
    ("integrator", "steps = 10"),
];

/// `BASE` with `line` in TOML section `section` (replacing the base's line
/// of the same key), as a scene file's text.
fn with_line(section: &str, line: &str) -> String {
    let key = |l: &str| l.split('=').next().unwrap_or("").trim().to_string();
    // A top-level key that names a base section (`integrator = 3`) takes
    // its place.
    let mut lines: Vec<(&str, &str)> = BASE
        .iter()
        .copied()
        .filter(|(s, l)| !(*s == section && key(l) == key(line)))
        .filter(|(s, _)| !(section.is_empty() && *s == key(line)))
        .collect();
    lines.push((section, line));
    let mut text = String::new();
    for (_, l) in lines.iter().filter(|(s, _)| s.is_empty()) {
        text.push_str(l);
        text.push('\n');
    }
    let mut sections: Vec<&str> = lines
        .iter()
        .map(|(s, _)| *s)
        .filter(|s| !s.is_empty())
        .collect();
    sections.dedup();
    for s in sections {
        text.push_str(&format!("[{s}]\n"));
        for (_, l) in lines.iter().filter(|(t, _)| *t == s) {
            text.push_str(l);
            text.push('\n');
        }
    }
    text
}

/// What `reeb check` says of `scene` (which it must refuse), its path out.
fn refusal(dir: &Path, scene: &str) -> String {
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let o = crate::common::runs::reeb(&["check", path.to_str().unwrap()]);
    let said = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "reeb check accepted:\n{scene}\n{said}");
    let line = said
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or(&said)
        .to_string();
    line.trim_start_matches("error: ")
        .replace(path.to_str().unwrap(), "scene.toml")
}

/// A table cell: `|` escaped, on one line.
fn cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

#[test]
fn the_scene_reference_lists_every_key_the_parser_accepts() {
    use reeb::scene::keys::TABLES;
    let dir = crate::common::runs::tmp("docs", "scene-keys");
    let mut text = String::new();
    for table in TABLES {
        let title = match table.section {
            "" => table.name.to_string(),
            _ => format!("`{}`", table.name),
        };
        text.push_str(&format!(
            "\n### {title}\n\n| key | value | default | meaning | refused, for example |\n|---|---|---|---|---|\n"
        ));
        for k in table.keys {
            let said = refusal(&dir, &with_line(table.section, k.bad));
            text.push_str(&format!(
                "| `{}` | {} | {} | {} | `{}` → {} |\n",
                k.name,
                cell(k.value),
                cell(k.default),
                cell(k.meaning),
                cell(k.bad),
                cell(&format!("`` {said} ``")),
            ));
        }
    }
    generated("docs/scene-reference.md", "keys", &text);
}

/// Scenes that, between them, write every array reeb writes: every
/// observer, every indicator with its running values, a stop condition.
const EVERY_OUTPUT: &[&str] = &[
    r#"model = "van_der_pol"
[params]
epsilon = { linspace = [0.5, 3.0, 4] }
[initial]
q = { linspace = [1.0, 2.0, 3] }
[integrator]
scheme = "s2"
dt = 0.05
steps = 400
[output]
final = ["q", "s"]
trajectory = { every = 100, vars = ["q"] }
poincare = { crossing = "q", value = 0.0, vars = ["s"], max_points = 4 }
cycle = true
average = ["q"]
resonance = { var = "q", ratios = [[1, 1]], tolerance = 10.0 }
stop = "t > 15"
attractors = { max_period = 2, skip = 0.0 }
"#,
    r#"model = "spin_orbit"
[params]
eccentricity = 0.1
epsilon = 0.05
[initial]
q = { linspace = [0.0, 6.0, 3] }
p = { linspace = [0.5, 1.5, 2] }
[integrator]
scheme = "s2"
dt = 0.1
steps = 200
[output]
final = ["q"]
trajectory = { every = 50, vars = ["p"] }
lyapunov = { vectors = 2 }
fli = true
megno = true
sali = true
gali = { k = 2 }
"#,
];

/// What each array reeb writes holds, by its name with the variables'
/// names as `<var>`.
const ARRAY_MEANINGS: &[(&str, &str)] = &[
    ("axis_<axis>", "the values of each axis of the ensemble"),
    ("final_<var>", "the final value (NaN if the trajectory became non-finite; where it stopped, if `output.stop` stopped it)"),
    ("trajectory_<var>", "every `every` steps from step 0 (`output.trajectory`)"),
    ("poincare_<var>", "the section's points, NaN-padded (`output.poincare`)"),
    ("poincare_count", "the number of section points found"),
    ("cycle_amplitude", "half the peak-to-peak range (`output.cycle`)"),
    ("cycle_period", "the least-squares period of the upward crossings"),
    ("mean_<var>", "the time average after the skipped fraction (`output.average`)"),
    ("resonance", "the index into `output.resonance.ratios` of the p:q the mean is within tolerance of, −1 for none"),
    ("lyapunov", "finite-time Lyapunov exponents, largest first (`output.lyapunov`)"),
    ("fli", "the fast Lyapunov indicator at the last sample (`output.fli`)"),
    ("megno", "MEGNO's ⟨Y⟩ at the last sample (`output.megno`)"),
    ("sali", "SALI at the last sample (`output.sali`)"),
    ("gali", "GALI_k at the last sample (`output.gali`)"),
    ("trajectory_lyapunov", "the exponents' running values per frame (with `output.trajectory`)"),
    ("trajectory_fli", "the FLI per frame"),
    ("trajectory_megno", "MEGNO per frame"),
    ("trajectory_sali", "SALI per frame"),
    ("trajectory_gali", "GALI_k per frame"),
    ("attractor_period", "the period of the cycle the orbit's samples end on (1: a fixed point), 0 aperiodic, −1 escaped (`output.attractors`)"),
    ("transient", "the sample from which on they recur with that period (−1: none)"),
    ("attractor_points_<var>", "the last `max_period` samples, oldest first (NaN where fewer were taken)"),
    ("attractor", "the label of the attractor the orbit ends on, 0 the largest basin, −1 escape (see `attractors.json`)"),
    ("status", "0 ran to the end, 1 became non-finite, 2 stopped by `output.stop`"),
    ("status_step", "the step it became non-finite at or stopped after (−1: neither)"),
];

/// The `.npy` header's element type, as numpy names it.
fn dtype(path: &Path) -> &'static str {
    let (header, _) = crate::common::npy(path);
    for (code, name) in [
        ("'<f4'", "float32"),
        ("'<f8'", "float64"),
        ("'<i4'", "int32"),
        ("'<i8'", "int64"),
        ("'|u1'", "uint8"),
        ("'<u4'", "uint32"),
    ] {
        if header.contains(code) {
            return name;
        }
    }
    panic!("{}: element type not known here: {header}", path.display())
}

/// The arrays of the run in `out`: each one's name (a variable's as
/// `<var>`, an axis's as `<axis>`), its dimensions after the ensemble's
/// axes, and its element type.
fn written_arrays(out: &Path) -> Vec<(String, String, &'static str)> {
    let summary = crate::common::runs::summary(out);
    let names = |dims: &serde_json::Value| -> Vec<String> {
        let dims = dims.as_array().map_or(&[][..], |d| d.as_slice());
        dims.iter()
            .filter_map(|x| x.as_str())
            .map(String::from)
            .collect()
    };
    // The ensemble's axes: what `status` has, one value per trajectory.
    let axes = names(&summary["dims"]["status"]);
    let vars = ["q", "p", "s", "t"];
    let files = summary["files"].as_array().unwrap().iter();
    let stems = files.filter_map(|f| f.as_str()?.strip_suffix(".npy"));
    stems
        .map(|stem| {
            let general = match stem.rsplit_once('_') {
                Some(("axis", _)) => "axis_<axis>".to_string(),
                Some((head, var)) if vars.contains(&var) => format!("{head}_<var>"),
                _ => stem.to_string(),
            };
            let inner: Vec<String> = names(&summary["dims"][stem])
                .into_iter()
                .filter(|x| !axes.contains(x))
                .collect();
            let t = dtype(&out.join(format!("{stem}.npy")));
            (general, inner.join(", "), t)
        })
        .collect()
}

/// The outputs page's table of arrays is what reeb writes: each array's
/// name, its dimensions (after the ensemble's axes) and its element type in
/// an f32 and an f64 run, read from `summary.json` and the files.
#[test]
fn the_outputs_page_lists_every_array_reeb_writes() {
    use crate::common::runs::{s, tmp};
    use std::collections::BTreeMap;
    // name → (dims after the axes, dtype in f32, dtype in f64)
    let mut arrays: BTreeMap<String, (String, String, String)> = BTreeMap::new();
    for (k, text) in EVERY_OUTPUT.iter().enumerate() {
        let dir = tmp("docs-outputs", &k.to_string());
        let scene = dir.join("scene.toml");
        std::fs::write(&scene, text).unwrap();
        for precision in ["f32", "f64"] {
            let out = dir.join(precision);
            let run = ["run", s(&scene), "--out", s(&out), "--backend", "cpu"];
            ok(&[&run[..], &["--precision", precision]].concat());
            for (name, dims, t) in written_arrays(&out) {
                let row = arrays
                    .entry(name)
                    .or_insert_with(|| (dims, String::new(), String::new()));
                match precision {
                    "f32" => row.1 = t.to_string(),
                    _ => row.2 = t.to_string(),
                }
            }
        }
    }
    let mut table = String::from("\n| array | dimensions after the axes | f32 run | f64 run | content |\n|---|---|---|---|---|\n");
    for (name, meaning) in ARRAY_MEANINGS {
        let Some((dims, f32, f64)) = arrays.remove(*name) else {
            panic!(
                "no scene of EVERY_OUTPUT writes {name}: add one, or remove it from ARRAY_MEANINGS"
            );
        };
        let dims = match (*name, dims.is_empty()) {
            ("axis_<axis>", _) => "its own".to_string(),
            (_, true) => "—".to_string(),
            _ => format!("`{dims}`"),
        };
        table.push_str(&format!(
            "| `{name}.npy` | {dims} | {f32} | {f64} | {meaning} |\n"
        ));
    }
    assert!(
        arrays.is_empty(),
        "arrays without a meaning in ARRAY_MEANINGS: {:?}",
        arrays.keys()
    );
    table.push('\n');
    generated("docs/outputs.md", "arrays", &table);
}
