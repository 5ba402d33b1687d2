//! The command-line reference and the help texts: `docs/cli.md` is exactly what `relight
//! help-markdown` prints (a build without `--features view` checks every verb but `view`,
//! whose options only that feature has), and no `--help` text names the development history
//! (issue or session numbers, numbered sections of the results log).

use std::path::Path;
mod common;
use common::{relight, stderr, stdout};

/// The command that regenerates `docs/cli.md` (as `relight help-markdown`'s header says).
const REGENERATE: &str =
    "cargo run --release -p relight-cli --features view -- help-markdown > docs/cli.md";

/// `relight help-markdown`'s output.
fn generated() -> String {
    let o = relight(&["help-markdown"]);
    assert!(o.status.success(), "help-markdown failed: {}", stderr(&o));
    stdout(&o)
}

/// `md` without what only a build with `--features view` can state: the `view` verb's
/// section and its line in the list of verbs.
fn without_view(md: &str) -> String {
    let mut out = String::new();
    let mut in_view = false;
    for line in md.lines() {
        if line.starts_with("## ") {
            in_view = line == "## relight view";
        }
        if !in_view && !line.starts_with("- [`view`]") {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

#[test]
fn docs_cli_md_is_what_help_markdown_prints() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/cli.md");
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}; generate it with `{REGENERATE}`", path.display()));
    let generated = generated();
    assert!(
        generated.contains(REGENERATE),
        "the header names another command"
    );
    let (mut want, mut got) = (generated, committed);
    if !cfg!(feature = "view") {
        println!("built without --features view: the `view` verb's section is not compared");
        (want, got) = (without_view(&want), without_view(&got));
    }
    let (want, got) = (want.trim_end(), got.trim_end());
    if want != got {
        let line = want
            .lines()
            .zip(got.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| want.lines().count().min(got.lines().count()));
        panic!(
            "docs/cli.md is out of date (first difference at line {}: generated {:?}, \
             committed {:?}); regenerate it with `{REGENERATE}`",
            line + 1,
            want.lines().nth(line).unwrap_or("<end>"),
            got.lines().nth(line).unwrap_or("<end>")
        );
    }
}

/// The lines of `text` that name the development history: `issue N`, `session N` (or their
/// plurals) or a section sign.
fn history_lines(text: &str) -> Vec<String> {
    text.lines()
        .filter(|line| {
            let l = line.to_lowercase();
            let numbered = |word: &str| {
                l.match_indices(word).any(|(i, w)| {
                    let rest = l[i + w.len()..].trim_start_matches('s');
                    let before = l[..i].chars().last();
                    before.is_none_or(|c| !c.is_alphanumeric())
                        && rest.starts_with(' ')
                        && rest[1..].starts_with(|c: char| c.is_ascii_digit())
                })
            };
            l.contains('§') || numbered("issue") || numbered("session")
        })
        .map(str::to_string)
        .collect()
}

#[test]
fn the_history_check_catches_what_it_should() {
    for bad in [
        "see issue 10",
        "Sessions 29-32",
        "docs/notes/2026-11-to-12-development-log.md §8",
        "(Issues 3)",
    ] {
        assert_eq!(history_lines(bad).len(), 1, "{bad}");
    }
    for good in [
        "no issue here",
        "sessions of 2 minutes",
        "tissue 3",
        "the 92 views",
    ] {
        assert!(history_lines(good).is_empty(), "{good}");
    }
}

#[test]
fn no_help_text_names_the_development_history() {
    let top = relight(&["--help"]);
    assert!(top.status.success(), "{}", stderr(&top));
    let top = stdout(&top);
    // The verbs, as `relight --help` lists them.
    let verbs: Vec<String> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|v| v != "help")
        .collect();
    assert!(verbs.len() >= 10, "too few verbs found in:\n{top}");
    let mut found = Vec::new();
    let mut check = |what: &str, text: &str| {
        for l in history_lines(text) {
            found.push(format!("{what}: {}", l.trim()));
        }
    };
    check("relight --help", &top);
    for v in &verbs {
        let o = relight(&[v, "--help"]);
        assert!(o.status.success(), "relight {v} --help: {}", stderr(&o));
        check(&format!("relight {v} --help"), &stdout(&o));
    }
    check("relight help-markdown", &generated());
    assert!(
        found.is_empty(),
        "help texts name issues, sessions or numbered sections of the results log instead of \
         saying what the software does (cite the paper):\n{}",
        found.join("\n")
    );
}
