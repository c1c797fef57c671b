//! Every fenced `sh` command of README.md runs, as a person would type it, with small sizes: each block
//! is one bash script (`set -e`) in a scratch directory, where `uavloc` is this build and `python3` the
//! test venv's; `cargo run --release --` is `uavloc`; a line ending in `&` runs in the background (the
//! next line comes a moment later, as typed) and must end with success too; `cargo test` lines are not run
//! (they are this run); `scenarios/…` are the repository's files. Sizes: `--steps` at most 200, `--runs` 2, domains made unique to this test. A
//! README command that no longer runs — a flag renamed, a file moved — fails CI here.

use crate::common;

use std::process::Command;

use common::{UAVLOC, scratch};

/// The `sh` blocks of `text`, each a list of command lines (comments and blank lines dropped).
fn sh_blocks(text: &str) -> Vec<Vec<String>> {
    let mut blocks = Vec::new();
    let mut current: Option<Vec<String>> = None;
    for line in text.lines() {
        let t = line.trim();
        match (&mut current, t) {
            (None, "```sh") => current = Some(Vec::new()),
            (Some(_), "```") => blocks.push(current.take().unwrap()),
            (Some(b), _) => {
                // A comment starts at a `#` after two spaces (or at the start).
                let code = match t.find("  #") {
                    Some(i) => t[..i].trim_end(),
                    None if t.starts_with('#') => "",
                    None => t,
                };
                if !code.is_empty() {
                    b.push(code.to_string());
                }
            }
            _ => {}
        }
    }
    blocks
}

/// The line as the test runs it: `uavloc` for `cargo run --release --`, smaller sizes, its own domains.
fn adapt(line: &str, domain: &str) -> String {
    let line = line.replace("cargo run --release --", "uavloc");
    // The repository's scenario files, from the scratch directory.
    let line = line.replace(" scenarios/", &format!(" {}/scenarios/", env!("CARGO_MANIFEST_DIR")));
    let words: Vec<&str> = line.split(' ').filter(|w| !w.is_empty()).collect();
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < words.len() {
        let w = words[i];
        let next = words.get(i + 1).copied();
        match (w, next) {
            ("--steps", Some(n)) if n.parse::<u64>().is_ok() => {
                out.push(format!("--steps {}", n.parse::<u64>().unwrap().min(200)));
                i += 2;
            }
            ("--runs", Some(n)) if n.parse::<u64>().is_ok() => {
                out.push("--runs 2".into());
                i += 2;
            }
            ("--domain", Some(d)) => {
                out.push(format!("--domain {domain}-{d}"));
                i += 2;
            }
            _ => {
                out.push(w.to_string());
                i += 1;
            }
        }
    }
    out.join(" ")
}

/// One block as a bash script: background lines remembered and waited for, each checked.
fn script(block: &[String], domain: &str) -> Option<String> {
    // A failing line ends the script; the background jobs go with it (they hold its output open).
    let mut s = String::from(
        "set -euo pipefail\npids=()\ntrap 'for p in \"${pids[@]}\"; do kill \"$p\" 2>/dev/null || true; done' EXIT\n",
    );
    let mut any = false;
    for line in block {
        if line.starts_with("cargo test") || line.starts_with("cargo bench") {
            continue;
        }
        any = true;
        let line = adapt(line, domain);
        match line.strip_suffix('&') {
            Some(bg) => s += &format!("{} &\npids+=($!)\nsleep 2\n", bg.trim_end()),
            None => s += &format!("{line}\n"),
        }
    }
    s += "for p in \"${pids[@]}\"; do wait \"$p\"; done\n";
    any.then_some(s)
}

#[test]
fn every_command_of_the_readme_runs() {
    let _scenario = common::scenario(module_path!());
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let blocks = sh_blocks(&readme);
    assert!(blocks.len() >= 8, "only {} sh blocks in README.md", blocks.len());
    let dir = scratch("readme");
    // `uavloc` and `python3` as the README means them; the examples where the README's paths say.
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::os::unix::fs::symlink(UAVLOC, bin.join("uavloc")).unwrap();
    // (A wrapper, not a link: a venv's python finds its packages from the path it was started by.)
    let python = bin.join("python3");
    std::fs::write(&python, format!("#!/bin/sh\nexec '{}' \"$@\"\n", common::python().display())).unwrap();
    std::fs::set_permissions(&python, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    std::os::unix::fs::symlink(root.join("examples"), dir.join("examples")).unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let domain = common::domain("readme", "tour");
    let mut ran = 0;
    for (k, block) in blocks.iter().enumerate() {
        let Some(s) = script(block, &domain) else { continue };
        let out = Command::new("bash").arg("-c").arg(&s).current_dir(&dir).env("PATH", &path).output().unwrap();
        assert!(
            out.status.success(),
            "README block {k} failed ({}):\n{s}\nstderr:\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        ran += 1;
    }
    assert!(ran >= 8, "only {ran} blocks ran");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn commands_are_read_as_typed() {
    let text = "x\n```sh\nuavloc a --steps 500   # the comment\n# only a comment\n\nb &\n```\n```text\nno\n```\n";
    assert_eq!(sh_blocks(text), [vec!["uavloc a --steps 500".to_string(), "b &".to_string()]]);
    assert_eq!(
        adapt("cargo run --release -- launch --steps 500 --domain lab1", "d"),
        "uavloc launch --steps 200 --domain d-lab1"
    );
    let s = script(&["uavloc x &".into(), "uavloc y".into(), "cargo test --workspace".into()], "d").unwrap();
    assert!(s.contains("uavloc x &\npids+=($!)") && s.contains("uavloc y\n") && !s.contains("cargo test"));
}

/// Every relative link of the documents (README, the top-level pages, docs/) points at a file that is
/// there.
#[test]
fn every_relative_link_of_the_documents_resolves() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut pages: Vec<std::path::PathBuf> =
        ["README.md", "ARCHITECTURE.md", "RELIABILITY.md", "BENCHMARKS.md", "EXPERIMENTS.md"]
            .iter()
            .map(|p| root.join(p))
            .collect();
    for dir in ["docs", "docs/paper", "docs/fusion"] {
        for e in std::fs::read_dir(root.join(dir)).unwrap().flatten() {
            if e.path().extension().is_some_and(|x| x == "md") {
                pages.push(e.path());
            }
        }
    }
    let mut broken = Vec::new();
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for (i, _) in text.match_indices("](") {
            let rest = &text[i + 2..];
            let Some(end) = rest.find(')') else { continue };
            let target = rest[..end].split('#').next().unwrap_or("");
            if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            if !page.parent().unwrap().join(target).exists() {
                broken.push(format!("{}: {target}", page.strip_prefix(root).unwrap().display()));
            }
        }
    }
    assert!(pages.len() >= 10, "{pages:?}");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}
