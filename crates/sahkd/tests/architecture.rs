//! ARCHITECTURE.md stays true when modules move: every module of the library's source tree
//! and every dependency of its Cargo.toml must be named there. A module `a/b/c.rs` (or
//! `a/b/c/mod.rs`) counts as named when one paragraph or table row of the document has both
//! `c` and its parent `b` in code spans (`` `c` ``, `` `b::c` ``, `` `b/` `` ...); a top-level
//! module needs its own name in a code span anywhere.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn architecture() -> String {
    let path = crate_dir().join("../../ARCHITECTURE.md");
    fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The document cut into blocks: each table row alone, other text split at blank lines.
fn blocks(doc: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for line in doc.lines() {
        if line.trim().is_empty() || line.starts_with('|') {
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
            if line.starts_with('|') {
                out.push(line.to_string());
            }
        } else {
            cur.push_str(line);
            cur.push('\n');
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// The identifiers inside the code spans of `text`.
fn code_words(text: &str) -> BTreeSet<String> {
    let mut words = BTreeSet::new();
    for (i, span) in text.split('`').enumerate() {
        if i % 2 == 1 {
            for w in span.split(|c: char| !(c.is_alphanumeric() || c == '_')) {
                if !w.is_empty() {
                    words.insert(w.to_string());
                }
            }
        }
    }
    words
}

/// Module paths (`["builders", "level", "scan"]`) of every source file under `dir`.
fn modules(dir: &Path, prefix: &[String], out: &mut Vec<Vec<String>>) {
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let mut here = prefix.to_vec();
        if path.is_dir() {
            here.push(name);
            out.push(here.clone());
            modules(&path, &here, out);
        } else if let Some(stem) = name.strip_suffix(".rs") {
            if stem != "mod" && stem != "lib" {
                here.push(stem.to_string());
                out.push(here);
            }
        }
    }
}

#[test]
fn architecture_names_every_module_of_the_library() {
    let doc = architecture();
    let blocks: Vec<BTreeSet<String>> = blocks(&doc).iter().map(|b| code_words(b)).collect();
    let mut all = Vec::new();
    modules(&crate_dir().join("src"), &[], &mut all);
    assert!(all.len() > 40, "found only {} modules", all.len());
    let missing: Vec<String> = all
        .iter()
        .filter(|m| {
            let name = &m[m.len() - 1];
            match m.len() {
                1 => !blocks.iter().any(|b| b.contains(name)),
                n => !blocks
                    .iter()
                    .any(|b| b.contains(name) && b.contains(&m[n - 2])),
            }
        })
        .map(|m| m.join("/"))
        .collect();
    assert!(
        missing.is_empty(),
        "ARCHITECTURE.md does not name these modules of crates/sahkd/src (with their parent \
         in the same paragraph or table row): {missing:?}"
    );
}

#[test]
fn architecture_names_every_dependency_of_the_library() {
    let doc = architecture();
    let row = doc
        .lines()
        .find(|l| l.starts_with("| `crates/sahkd` |"))
        .expect("a row for crates/sahkd in ARCHITECTURE.md's crate table");
    let manifest = fs::read_to_string(crate_dir().join("Cargo.toml")).unwrap();
    let mut section = String::new();
    let mut deps = Vec::new();
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            section = line.to_string();
        } else if section.ends_with("dependencies]")
            && !section.contains("dev-dependencies")
            && !section.contains("build-dependencies")
            && !line.is_empty()
            && !line.starts_with('#')
        {
            let name = line.split(['.', '=', ' ']).next().unwrap();
            deps.push(name.to_string());
        }
    }
    assert!(
        deps.contains(&"rayon".to_string()),
        "read no dependencies: {deps:?}"
    );
    let missing: Vec<&String> = deps.iter().filter(|d| !row.contains(d.as_str())).collect();
    assert!(
        missing.is_empty(),
        "ARCHITECTURE.md's row for crates/sahkd does not name these dependencies: {missing:?}"
    );
}
