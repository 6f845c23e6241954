//! The documentation's generated pages are what reeb itself says, so they
//! cannot drift: the command-line reference is every command's own help
//! (clap's), and the citation page's tables are `summary.json`'s
//! `references` for every scheme and built-in model. After a change,
//! `REEB_UPDATE_DOCS=1 cargo test --release --test suite docs::` rewrites them.

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
                format!("[{k}]")
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
        text.push_str(&format!("{}. {p}\n", k + 1));
    }
    text.push('\n');
    generated("docs/cite.md", "references", &text);
}
