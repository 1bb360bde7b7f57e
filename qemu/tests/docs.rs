//! The documentation's links (host, `cargo test`): every relative link and image in README.md and
//! docs/**/*.md resolves, anchors included, as `docs/check_links.py` checks them (run here with
//! the machine's python3).
use std::path::Path;
use std::process::Command;

/// `docs/check_links.py` passes on the repository's README and book. It fails on a link to a
/// missing page, a missing figure or a heading that is not there
/// (`a_broken_link_is_found` shows it on a copy).
#[test]
fn every_link_and_image_in_the_docs_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let o = Command::new("python3")
        .arg(root.join("docs/check_links.py"))
        .output()
        .expect("python3 runs");
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The checker itself finds a broken link, image and anchor (on a copy of the book with three
/// broken targets added to its README).
#[test]
fn a_broken_link_is_found() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR")).join("docs-links");
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(tmp.join("docs")).unwrap();
    std::fs::copy(
        root.join("docs/check_links.py"),
        tmp.join("docs/check_links.py"),
    )
    .unwrap();
    std::fs::write(
        tmp.join("README.md"),
        "# Title\n\n[a](docs/nowhere.md) ![b](docs/figures/none.png) [c](#no-such-heading)\n",
    )
    .unwrap();
    let o = Command::new("python3")
        .arg(tmp.join("docs/check_links.py"))
        .output()
        .expect("python3 runs");
    let out = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{out}");
    for broken in ["nowhere.md", "none.png", "no-such-heading"] {
        assert!(out.contains(broken), "{broken} not reported: {out}");
    }
}

/// The commands the docs give to run: every line of a ```sh block and every inline code span
/// that starts with `cargo` or `millac-qemu`, from README.md and docs/**/*.md, with its file.
fn documented_commands(root: &Path) -> Vec<(String, String)> {
    let mut files = vec![root.join("README.md")];
    let mut dirs = vec![root.join("docs")];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "md") {
                files.push(p);
            }
        }
    }
    files.sort();
    let mut out = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let name = f.strip_prefix(root).unwrap().display().to_string();
        let mut in_sh = false;
        for line in text.lines() {
            let t = line.trim();
            if let Some(lang) = t.strip_prefix("```") {
                in_sh = !in_sh && lang.trim() == "sh";
                continue;
            }
            if in_sh {
                // A comment after the command: two spaces and `#`.
                let cmd = t.split("  #").next().unwrap().trim();
                if !cmd.is_empty() && !cmd.starts_with('#') {
                    out.push((name.clone(), cmd.to_string()));
                }
                continue;
            }
            for (i, span) in line.split('`').enumerate() {
                if i % 2 == 1 && (span.starts_with("cargo ") || span.starts_with("millac-qemu ")) {
                    out.push((name.clone(), span.to_string()));
                }
            }
        }
    }
    out
}

/// Why a documented command does not exist, if it does not: a `cargo run` of the CLI names a
/// subcommand that answers `--help` and options that its help lists; an example or a test target
/// names a file in qemu/examples or qemu/tests, and an example's options are in its source; a
/// cargo alias is in .cargo/config.toml. Other programs (socat, python, cargo install) are not
/// ours to check.
fn missing(root: &Path, cli: &Path, cmd: &str) -> Option<String> {
    let words: Vec<&str> = cmd.split_whitespace().collect();
    let (tool, rest) = words.split_first()?;
    let after = |w: &[&str]| -> Vec<String> {
        // The options (`--name`, also inside `[...]` or `a|b` alternatives, without `=value`).
        w.iter()
            .flat_map(|s| s.split('|'))
            .map(|s| s.trim_matches(['[', ']', '(', ')', ',']))
            .filter(|s| s.starts_with("--") && s.len() > 2)
            .map(|s| s.split('=').next().unwrap().to_string())
            .collect()
    };
    let target_file = |dir: &str, flag: &str| -> Option<std::path::PathBuf> {
        let i = rest.iter().position(|w| *w == flag)?;
        Some(root.join(dir).join(format!("{}.rs", rest.get(i + 1)?)))
    };
    let sep = rest.iter().position(|w| *w == "--");
    if *tool == "cargo" {
        let sub = *rest.first()?;
        if let Some(example) = target_file("qemu/examples", "--example") {
            if !example.is_file() {
                return Some(format!("no example {}", example.display()));
            }
            let src = std::fs::read_to_string(&example).unwrap();
            let flags = sep.map(|i| after(&rest[i + 1..])).unwrap_or_default();
            return flags
                .into_iter()
                .find(|f| !src.contains(&format!("\"{f}\"")))
                .map(|f| format!("{} does not take {f}", example.display()));
        }
        if let Some(test) = target_file("qemu/tests", "--test") {
            return (!test.is_file()).then(|| format!("no test target {}", test.display()));
        }
        match sub {
            "run" => {
                // The CLI (the workspace's default binary): `cargo run [--release] -- SUB ...`.
                let args = &rest[sep? + 1..];
                return cli_missing(cli, args, &after(args));
            }
            "test" | "build" | "install" | "fmt" | "clippy" | "doc" => return None,
            alias => {
                let config = std::fs::read_to_string(root.join(".cargo/config.toml")).unwrap();
                let defined = config
                    .lines()
                    .any(|l| l.split('=').next().unwrap().trim() == alias);
                return (!defined).then(|| format!("no cargo alias {alias}"));
            }
        }
    }
    if *tool == "millac-qemu" {
        return cli_missing(cli, rest, &after(rest));
    }
    None
}

/// `millac-qemu SUB --help` succeeds and lists every option in `flags`.
fn cli_missing(cli: &Path, args: &[&str], flags: &[String]) -> Option<String> {
    let sub = args.first().filter(|s| !s.starts_with('-'));
    let mut c = Command::new(cli);
    c.args(sub).arg("--help");
    let o = c.output().expect("the CLI runs");
    let help = String::from_utf8_lossy(&o.stdout).to_string();
    if !o.status.success() {
        return Some(format!(
            "`millac-qemu {} --help` fails: {}",
            sub.unwrap_or(&""),
            String::from_utf8_lossy(&o.stderr)
        ));
    }
    flags
        .iter()
        .find(|f| *f != "--help" && !help.contains(f.as_str()))
        .map(|f| format!("`millac-qemu {}` has no option {f}", sub.unwrap_or(&"")))
}

/// Every command the docs give to run exists: the CLI's subcommands and their options, the
/// examples, the test targets and the cargo aliases they name.
#[test]
fn every_documented_command_exists() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let cli = Path::new(env!("CARGO_BIN_EXE_millac-qemu"));
    let commands = documented_commands(&root);
    assert!(commands.len() > 30, "{} commands found", commands.len());
    eprintln!("{} documented commands", commands.len());
    let bad: Vec<String> = commands
        .iter()
        .filter_map(|(file, cmd)| {
            missing(&root, cli, cmd).map(|why| format!("{file}: `{cmd}`: {why}"))
        })
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The check finds a subcommand, an option, an example and an alias that do not exist.
#[test]
fn a_command_that_does_not_exist_is_found() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let cli = Path::new(env!("CARGO_BIN_EXE_millac-qemu"));
    for cmd in [
        "cargo run --release -- runn program.nc",
        "cargo run --release -- run program.nc --no-such-option",
        "cargo run -p millac-qemu --release --example no_such_example",
        "cargo run -p millac-qemu --release --example ac_cost -- --no-such-flag",
        "cargo no-such-alias",
        "millac-qemu host x.nc --no-such-option",
    ] {
        assert!(missing(&root, cli, cmd).is_some(), "{cmd} passed");
    }
    for cmd in [
        "cargo run --release -- run program.nc --nc-only",
        "cargo run -p millac-qemu --release --example ac_cost -- --monitors",
        "cargo fw",
    ] {
        assert_eq!(missing(&root, cli, cmd), None, "{cmd}");
    }
}
