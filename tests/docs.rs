//! The manual (docs/ outside docs/journal/, and README.md) says what is
//! true now: no commit hashes, no names of work branches or attempts, no
//! issue-number narrative (those belong to docs/journal/ and CHANGELOG.md).
//! Every relative markdown link in the docs, README.md and CHANGELOG.md
//! points at a file that exists (and at a heading of it, for `#anchor`s), and
//! every `docs/....md` path named in the sources exists.

use std::fs;
use std::path::{Path, PathBuf};

/// Words and phrases of the journal that the manual does not use: names of
/// work branches and attempts, and the narrative of what was tried.
/// Matched case-insensitively as substrings.
const FORBIDDEN: &[&str] = &[
    "branch `",
    "`onset`",
    "`acquire`",
    "`accum`",
    "locked-exponent",
    "probe-bias",
    "sigma-growth",
    "sweeps2",
    "bisect171",
    "smallmem",
    "ekfcore",
    "not kept",
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Files under `dir` whose name ends in `.ext`, recursively, sorted.
fn files_under(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == ext) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn markdown_under(dir: &Path) -> Vec<PathBuf> {
    files_under(dir, "md")
}

/// The manual's pages: docs/ outside docs/journal/, and README.md.
fn manual_pages(root: &Path) -> Vec<PathBuf> {
    let journal = root.join("docs").join("journal");
    let mut pages: Vec<PathBuf> = markdown_under(&root.join("docs"))
        .into_iter()
        .filter(|p| !p.starts_with(&journal))
        .collect();
    let readme = root.join("README.md");
    if readme.exists() {
        pages.push(readme);
    }
    pages
}

/// Tokens of 7 to 40 lowercase hex digits holding both a digit and a letter
/// (a shortened or full commit hash), with their line numbers.
fn hash_like(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        for token in line.split(|c: char| !c.is_ascii_alphanumeric()) {
            let hex = token.chars().all(|c| matches!(c, '0'..='9' | 'a'..='f'));
            let digit = token.chars().any(|c| c.is_ascii_digit());
            let letter = token.chars().any(|c| c.is_ascii_alphabetic());
            if (7..=40).contains(&token.len()) && hex && digit && letter {
                found.push((n + 1, token.to_string()));
            }
        }
    }
    found
}

/// "issue 11", "issues 10-13": the narrative of the work, not the manual's.
fn issue_numbers(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let lower = line.to_lowercase();
        for word in ["issue ", "issues "] {
            for (i, _) in lower.match_indices(word) {
                let after = &lower[i + word.len()..];
                if after.starts_with(|c: char| c.is_ascii_digit()) {
                    found.push((n + 1, line.trim().to_string()));
                }
            }
        }
    }
    found
}

fn forbidden_words(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let lower = line.to_lowercase();
        for word in FORBIDDEN {
            if lower.contains(word) {
                found.push((n + 1, (*word).to_string()));
            }
        }
    }
    found
}

/// What the manual must not hold, one line per finding.
fn manual_findings(root: &Path) -> Vec<String> {
    let mut findings = Vec::new();
    for page in manual_pages(root) {
        let text = fs::read_to_string(&page).expect("readable page");
        let name = page
            .strip_prefix(root)
            .unwrap_or(&page)
            .display()
            .to_string();
        for (line, token) in hash_like(&text) {
            findings.push(format!("{name}:{line}: commit-hash-like `{token}`"));
        }
        for (line, word) in forbidden_words(&text) {
            findings.push(format!("{name}:{line}: journal word `{word}`"));
        }
        for (line, what) in issue_numbers(&text) {
            findings.push(format!("{name}:{line}: issue number: {what}"));
        }
    }
    findings
}

/// GitHub's anchor of a heading: lowercase, spaces to `-`, punctuation
/// other than `-` and `_` dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

fn anchors(text: &str) -> Vec<String> {
    text.lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| slug(l.trim_start_matches('#')))
        .collect()
}

/// Targets of the inline links `[text](target)` of a markdown text, outside
/// code blocks.
fn link_targets(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    let mut fenced = false;
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        for (i, _) in line.match_indices("](") {
            let rest = &line[i + 2..];
            if let Some(end) = rest.find(')') {
                found.push((n + 1, rest[..end].to_string()));
            }
        }
    }
    found
}

/// Relative links of `files` that point at a missing file or heading.
fn broken_links(root: &Path, files: &[PathBuf]) -> Vec<String> {
    let mut broken = Vec::new();
    for file in files {
        let text = fs::read_to_string(file).expect("readable page");
        let name = file
            .strip_prefix(root)
            .unwrap_or(file)
            .display()
            .to_string();
        let dir = file.parent().expect("a file has a folder");
        for (line, target) in link_targets(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let resolved = if path.is_empty() {
                file.clone()
            } else {
                dir.join(path)
            };
            if !resolved.exists() {
                broken.push(format!("{name}:{line}: missing `{target}`"));
                continue;
            }
            if let Some(anchor) = anchor {
                let heads = fs::read_to_string(&resolved)
                    .map(|t| anchors(&t))
                    .unwrap_or_default();
                if !heads.iter().any(|h| h == anchor) {
                    broken.push(format!("{name}:{line}: no heading `#{anchor}`"));
                }
            }
        }
    }
    broken
}

fn all_markdown(root: &Path) -> Vec<PathBuf> {
    let mut files = markdown_under(&root.join("docs"));
    for top in ["README.md", "CHANGELOG.md"] {
        let p = root.join(top);
        if p.exists() {
            files.push(p);
        }
    }
    files
}

/// `docs/....md` paths named in the sources that do not exist.
fn missing_doc_paths(root: &Path) -> Vec<String> {
    let mut files: Vec<PathBuf> = ["src", "examples", "tests", "benches"]
        .iter()
        .flat_map(|dir| files_under(&root.join(dir), "rs"))
        // This file names example paths of its own.
        .filter(|p| !p.ends_with("tests/docs.rs"))
        .collect();
    files.push(root.join("README.md"));
    let mut missing = Vec::new();
    for file in files {
        let Ok(text) = fs::read_to_string(&file) else {
            continue;
        };
        let name = file
            .strip_prefix(root)
            .unwrap_or(&file)
            .display()
            .to_string();
        for (n, line) in text.lines().enumerate() {
            for (i, _) in line.match_indices("docs/") {
                // Only a path at the start of a word (not `target/docs/`).
                if line[..i].ends_with(|c: char| c.is_alphanumeric() || c == '/') {
                    continue;
                }
                let path: String = line[i..]
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || matches!(c, '/' | '.' | '-' | '_'))
                    .collect();
                let path = path.trim_end_matches('.');
                if path.ends_with(".md") && !root.join(path).exists() {
                    missing.push(format!("{name}:{}: `{path}`", n + 1));
                }
            }
        }
    }
    missing
}

#[test]
fn the_manual_holds_no_hashes_branch_names_or_issue_numbers() {
    let findings = manual_findings(&root());
    assert!(
        findings.is_empty(),
        "move these to docs/journal/ or rewrite them:\n{}",
        findings.join("\n")
    );
}

#[test]
fn relative_links_in_the_docs_resolve() {
    let root = root();
    let broken = broken_links(&root, &all_markdown(&root));
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn docs_paths_named_in_the_sources_exist() {
    let missing = missing_doc_paths(&root());
    assert!(missing.is_empty(), "missing docs:\n{}", missing.join("\n"));
}

/// The checks themselves: a planted hash, a branch name, an issue number
/// and a broken link in a scratch tree are found; the journal is exempt.
#[test]
fn the_checks_find_what_is_planted() {
    let dir = std::env::temp_dir().join(format!("delaynav-docs-check-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(dir.join("docs").join("journal")).expect("scratch folders");
    fs::write(
        dir.join("docs").join("page.md"),
        "# Page\n\nMeasured on 1e93f65, seed 8833327133248184445.\n\
         See [the journal](journal/entry.md) and [gone](nowhere.md), [here](#page), [there](#nope).\n\
         On branch `probe-bias`; issue 11's row.\n",
    )
    .expect("scratch page");
    fs::write(
        dir.join("docs").join("journal").join("entry.md"),
        "# Entry\n\nOn 1e93f65, branch `probe-bias`, issue 11.\n",
    )
    .expect("scratch entry");

    let findings = manual_findings(&dir);
    let broken = broken_links(&dir, &all_markdown(&dir));
    let _ = fs::remove_dir_all(&dir);

    assert_eq!(findings.len(), 4, "{findings:#?}");
    assert!(findings[0].contains("`1e93f65`"), "{findings:#?}");
    assert!(findings.iter().all(|f| f.starts_with("docs/page.md")));
    assert!(findings.iter().any(|f| f.contains("branch `")));
    assert!(findings.iter().any(|f| f.contains("probe-bias")));
    assert!(findings.iter().any(|f| f.contains("issue number")));
    assert_eq!(broken.len(), 2, "{broken:#?}");
    assert!(broken[0].contains("nowhere.md"));
    assert!(broken[1].contains("#nope"));
}

#[test]
fn hash_like_tokens_are_hex_with_a_digit_and_a_letter() {
    let text = "c6c2ae3 and 0439dd7, not 1234567, not defaced, not 0x1f2e3d4a, not abc12";
    let tokens: Vec<String> = hash_like(text).into_iter().map(|(_, t)| t).collect();
    assert_eq!(tokens, ["c6c2ae3", "0439dd7"]);
}
