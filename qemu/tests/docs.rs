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
