//! The source layout's rules (host, `cargo test`): no import circles between the modules of a
//! folder. A module that uses a sibling which uses it back (directly or round a longer loop) is a
//! knot: neither can be read, tested or moved without the other.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crates' source roots, from the workspace root.
const ROOTS: [&str; 5] = [
    "src",
    "hal/lm3s6965/src",
    "hal/nucleo-f446re/src",
    "qemu/src",
    "qemu/plant/src",
];

/// A module's code without its tests (`#[cfg(test)]` and all after it: tests may use anything)
/// and without its comments (a doc link is not a use).
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => &text[..],
    };
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The `.rs` files of `dir` and its folders, test modules left out.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut dirs = vec![dir.to_path_buf()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if p.is_dir() {
                dirs.push(p);
            } else if name.ends_with(".rs") && !name.starts_with("tests") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The module path of a file under its crate root (`nc/frame.rs` -> `nc::frame`, `nc/mod.rs` and
/// `nc.rs` -> `nc`; `lib.rs`, `main.rs` -> ``).
fn module_of(root: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(root).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts.join("::")
}

/// The sibling modules `module` refers to in `text` (`crate::a::b` or `super::b` where `b` is a
/// module beside it in the same folder).
fn sibling_uses(module: &str, text: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let parent = module.rsplit_once("::").map_or("", |(p, _)| p);
    let mut out = BTreeSet::new();
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    for (i, _) in text.match_indices("super::") {
        let name = ident(&text[i + 7..]);
        // `super::{a, b}`: the list is read below.
        if name.is_empty() {
            continue;
        }
        let m = if parent.is_empty() {
            name
        } else {
            format!("{parent}::{name}")
        };
        out.insert(m);
    }
    let prefix = if parent.is_empty() {
        "crate::".to_string()
    } else {
        format!("crate::{parent}::")
    };
    for (i, _) in text.match_indices(&prefix) {
        let name = ident(&text[i + prefix.len()..]);
        // `crate::{a, b}`: the list is read below (not a use of the crate root).
        if name.is_empty() {
            continue;
        }
        let m = if parent.is_empty() {
            name
        } else {
            format!("{parent}::{name}")
        };
        out.insert(m);
    }
    // `use super::{a, b}` and `use crate::parent::{a, b}` name several.
    for head in ["super::{".to_string(), format!("{prefix}{{")] {
        for (i, _) in text.match_indices(&head) {
            let list = &text[i + head.len()..];
            let list = &list[..list.find('}').unwrap_or(0)];
            for name in list.split(',').map(|s| ident(s.trim())) {
                let m = if parent.is_empty() {
                    name
                } else {
                    format!("{parent}::{name}")
                };
                out.insert(m);
            }
        }
    }
    out.retain(|m| {
        m != module && modules.contains(m) && m.rsplit_once("::").map_or("", |(p, _)| p) == parent
    });
    out
}

/// The circles of a module graph: each as the modules round it, from its smallest.
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> BTreeSet<Vec<String>> {
    let mut found = BTreeSet::new();
    for start in graph.keys() {
        // Depth-first paths from `start` back to it, through modules after it only (so each
        // circle is found once, from its smallest module).
        let mut stack = vec![(start.clone(), vec![start.clone()])];
        while let Some((at, path)) = stack.pop() {
            for next in graph.get(&at).into_iter().flatten() {
                if next == start {
                    found.insert(path.clone());
                } else if next > start && !path.contains(next) {
                    let mut p = path.clone();
                    p.push(next.clone());
                    stack.push((next.clone(), p));
                }
            }
        }
    }
    found
}

/// The import graph of one crate.
fn graph(root: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let files = files(root);
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(root, f)).collect();
    files
        .iter()
        .map(|f| {
            let m = module_of(root, f);
            let uses = sibling_uses(&m, &code(f), &modules);
            (m, uses)
        })
        .collect()
}

#[test]
fn no_module_uses_a_sibling_that_uses_it_back() {
    let ws = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut bad = Vec::new();
    for root in ROOTS {
        let g = graph(&ws.join(root));
        assert!(g.len() >= 3, "{root}: {} modules", g.len());
        for c in circles(&g) {
            bad.push(format!("{root}: {}", c.join(" -> ")));
        }
    }
    assert!(bad.is_empty(), "import circles:\n{}", bad.join("\n"));
}

/// The check finds a circle of two and one of three, and none in a chain.
#[test]
fn circles_are_found() {
    let set = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>();
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a".to_string(), set(&["b"])),
        ("b".to_string(), set(&["a", "c"])),
        ("c".to_string(), set(&["d"])),
        ("d".to_string(), set(&["e"])),
        ("e".to_string(), set(&["c"])),
        ("f".to_string(), set(&["a"])),
    ]
    .into_iter()
    .collect();
    let c = circles(&g);
    assert!(c.contains(&vec!["a".to_string(), "b".to_string()]), "{c:?}");
    assert!(
        c.contains(&vec!["c".to_string(), "d".to_string(), "e".to_string()]),
        "{c:?}"
    );
    assert_eq!(c.len(), 2, "{c:?}");
    // And the parsing: `super::` and `crate::parent::` uses of a sibling, braces included.
    let modules = set(&["nc::block", "nc::frame", "nc::operator"]);
    let uses = sibling_uses(
        "nc::frame",
        "use super::{block::Block, operator};\nlet x = crate::nc::block::RAMP_MAX;",
        &modules,
    );
    assert_eq!(uses, set(&["nc::block", "nc::operator"]));
    // A crate root's module naming its siblings in braces uses them, not the root.
    let root = set(&["", "program", "results", "semihost"]);
    let uses = sibling_uses("program", "use crate::{results, semihost};", &root);
    assert_eq!(uses, set(&["results", "semihost"]));
}
