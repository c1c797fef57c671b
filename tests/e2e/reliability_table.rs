//! RELIABILITY.md's tables name, on every row, the tests that assert the row: `path` (`name`, `name…`).
//! Each row must name at least one test function, each file must exist and each name must be a function
//! in it (a name ending in `…` is the start of one). A row whose test is renamed, removed or never was
//! fails here.

use std::path::Path;

/// The test references of one table cell: (file, function name, whether the name is a prefix).
fn references(cell: &str) -> Vec<(String, String, bool)> {
    let mut out = Vec::new();
    let mut rest = cell;
    while let Some(start) = rest.find('`') {
        let after = &rest[start + 1..];
        let Some(end) = after.find('`') else { break };
        let token = &after[..end];
        rest = &after[end + 1..];
        if !token.ends_with(".rs") {
            continue;
        }
        // The names in the parentheses right after the file.
        let trimmed = rest.trim_start();
        if let Some(inner) = trimmed.strip_prefix('(').and_then(|t| t.split_once(')')).map(|(i, _)| i) {
            for name in inner.split('`').skip(1).step_by(2) {
                let (name, prefix) = match name.strip_suffix('…') {
                    Some(n) => (n, true),
                    None => (name, false),
                };
                out.push((token.to_string(), name.to_string(), prefix));
            }
        }
    }
    out
}

/// Whether `src` defines a function `name` (or one starting with it, for a prefix).
fn defines(src: &str, name: &str, prefix: bool) -> bool {
    src.match_indices(&format!("fn {name}")).any(|(i, m)| {
        let next = src[i + m.len()..].chars().next();
        prefix || matches!(next, Some('(') | Some('<'))
    })
}

#[test]
fn every_row_of_the_reliability_tables_names_tests_that_exist() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("RELIABILITY.md")).unwrap();
    let mut rows = 0;
    let mut problems = Vec::new();
    for line in text.lines().filter(|l| l.starts_with('|') && !l.starts_with("|---") && !l.starts_with("| fault |")) {
        rows += 1;
        let cell = line.trim_end_matches('|').rsplit('|').next().unwrap_or("");
        let refs = references(cell);
        if refs.is_empty() {
            problems.push(format!("names no test function: {line}"));
        }
        for (file, name, prefix) in refs {
            match std::fs::read_to_string(root.join(&file)) {
                Err(e) => problems.push(format!("{file}: {e} (row: {line})")),
                Ok(src) if !defines(&src, &name, prefix) => problems.push(format!("{file} has no fn {name}")),
                Ok(_) => {}
            }
        }
    }
    assert!(rows >= 60, "only {rows} rows found: is the table still there?");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_checker_finds_names_and_prefixes() {
    let refs = references("`a/b.rs` (`x_y`, `z…`), `c.rs`");
    assert_eq!(refs, [("a/b.rs".to_string(), "x_y".to_string(), false), ("a/b.rs".to_string(), "z".to_string(), true)]);
    assert!(defines("fn x_y() {}", "x_y", false) && !defines("fn x_yz() {}", "x_y", false));
    assert!(defines("fn x_yz() {}", "x_y", true));
}
