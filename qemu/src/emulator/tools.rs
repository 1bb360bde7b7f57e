//! External tools the host tool needs (qemu-system-arm, sigrok-cli, a C compiler, the Rust target of
//! the firmware, the boards' linker wrapper flip-link) and the third-party senders its tests drive
//! (pygrbl-streamer, bCNC): find them and install the missing ones (apt-get when running as root;
//! `rustup target add` for a Rust target; `cargo install` for a program from crates.io; a Python
//! virtual environment and pip for a sender), and LinuxCNC's standalone interpreter rs274 (two
//! Debian packages downloaded and unpacked under the workspace's `target/`, not installed) (host).
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The Debian package that provides `program`, for the programs millac uses.
pub fn debian_package(program: &str) -> Option<&'static str> {
    match program {
        "qemu-system-arm" => Some("qemu-system-arm"),
        "sigrok-cli" => Some("sigrok-cli"),
        "cc" | "gcc" => Some("gcc"),
        "socat" => Some("socat"),
        _ => None,
    }
}

/// Looks `program` up on PATH.
pub fn find_on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|p| p.is_file())
}

/// True when the effective user id is 0 (read from /proc/self/status).
pub fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .and_then(|l| l.split_whitespace().nth(2).map(|e| e == "0"))
        })
        .unwrap_or(false)
}

/// Returns the path of `program`. If it is missing and we run as root, installs its Debian package
/// with `apt-get install -y` (running `apt-get update` first if that fails); otherwise returns an
/// error naming exactly what to install. Never silently succeeds without the tool.
pub fn ensure_tool(program: &str) -> Result<PathBuf> {
    if let Some(p) = find_on_path(program) {
        return Ok(p);
    }
    let package = debian_package(program).with_context(|| {
        format!("`{program}` not found on PATH and no known package provides it")
    })?;
    // One install at a time within this process (tests run in parallel); across processes apt
    // waits for the dpkg lock.
    static INSTALL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = INSTALL.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = find_on_path(program) {
        return Ok(p);
    }
    if !is_root() {
        bail!("`{program}` not found on PATH: install it with `sudo apt-get install -y {package}`");
    }
    apt_install(package).with_context(|| format!("`{program}` missing"))?;
    find_on_path(program).with_context(|| {
        format!("installed package {package} but `{program}` is still not on PATH")
    })
}

/// `apt-get install -y package` (running `apt-get update` first if that fails), waiting up to
/// 5 min for another install's dpkg lock. Root only (the callers check).
fn apt_install(package: &str) -> Result<()> {
    let install = || {
        Command::new("apt-get")
            .args(["-o", "DPkg::Lock::Timeout=300", "install", "-y", package])
            .env("DEBIAN_FRONTEND", "noninteractive")
            .status()
    };
    if install().map(|s| s.success()).unwrap_or(false) {
        return Ok(());
    }
    let updated = Command::new("apt-get")
        .args(["-o", "DPkg::Lock::Timeout=300", "update"])
        .status();
    if matches!(updated, Ok(s) if s.success()) && install().map(|s| s.success()).unwrap_or(false) {
        return Ok(());
    }
    bail!("`apt-get install -y {package}` failed")
}

/// A C compiler: `$CC`, else `cc` or `gcc` (installing gcc as root when none is present).
pub fn ensure_c_compiler() -> Result<PathBuf> {
    if let Ok(cc) = std::env::var("CC") {
        if let Some(p) = find_on_path(&cc) {
            return Ok(p);
        }
    }
    find_on_path("cc").map_or_else(|| ensure_tool("gcc"), Ok)
}

/// Makes sure the Rust standard library for `target` is installed for the toolchain that builds in
/// `dir` (the workspace, where `rust-toolchain.toml` picks the toolchain): if the sysroot lacks
/// `lib/rustlib/<target>`, runs `rustup target add <target>` there (saying so on stderr). rustup
/// installs a toolchain file's targets only when it installs the toolchain itself, so a machine
/// that already had stable needs this. Returns whether it installed the target.
pub fn ensure_rust_target(target: &str, dir: &Path) -> Result<bool> {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    // One `rustup target add` at a time within this process (tests build in parallel).
    static ADD: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = ADD.lock().unwrap_or_else(|e| e.into_inner());
    ensure_rust_target_with(
        target,
        Path::new(&rustc),
        find_on_path("rustup").as_deref(),
        dir,
    )
}

/// The sysroot of `rustc` as run in `dir` (`rustc --print sysroot`).
fn rust_sysroot(rustc: &Path, dir: &Path) -> Result<PathBuf> {
    let out = Command::new(rustc)
        .args(["--print", "sysroot"])
        .current_dir(dir)
        .output()
        .with_context(|| format!("running `{} --print sysroot`", rustc.display()))?;
    if !out.status.success() {
        bail!(
            "`{} --print sysroot` failed ({}): {}",
            rustc.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()))
}

/// [`ensure_rust_target`] with the programs given: `rustc` (for the sysroot) and `rustup` (None:
/// not installed), both run in `dir`.
pub fn ensure_rust_target_with(
    target: &str,
    rustc: &Path,
    rustup: Option<&Path>,
    dir: &Path,
) -> Result<bool> {
    let sysroot = rust_sysroot(rustc, dir)?;
    let lib = sysroot.join("lib").join("rustlib").join(target);
    if lib.is_dir() {
        return Ok(false);
    }
    let Some(rustup) = rustup else {
        bail!(
            "the Rust target {target} is not installed (no {}) and `rustup` is not on PATH: \
             install it with `rustup target add {target}` (or your distribution's rust-std for {target})",
            lib.display()
        );
    };
    eprintln!("millac: the Rust target {target} is missing, running `rustup target add {target}`");
    let status = Command::new(rustup)
        .args(["target", "add", target])
        .current_dir(dir)
        .status()
        .with_context(|| format!("running `{} target add {target}`", rustup.display()))?;
    if !status.success() {
        bail!("`rustup target add {target}` failed ({status})");
    }
    if !rust_sysroot(rustc, dir)?
        .join("lib")
        .join("rustlib")
        .join(target)
        .is_dir()
    {
        bail!(
            "`rustup target add {target}` succeeded but {} is still missing",
            lib.display()
        );
    }
    Ok(true)
}

/// A host program that comes from crates.io (`cargo install`), with the version the project
/// builds with.
#[derive(Clone, Copy, Debug)]
pub struct CargoTool {
    /// The program's name (in `bin/` of cargo's install root, and on PATH when that is).
    pub program: &'static str,
    /// The crate that provides it.
    pub krate: &'static str,
    /// The version installed when it is missing (`cargo install --version`).
    pub version: &'static str,
}

/// flip-link, the linker wrapper of the real boards' firmware (target thumbv7em-none-eabihf in
/// .cargo/config.toml): it puts the stack below the statics, so an overflow faults instead of
/// overwriting them.
pub const FLIP_LINK: CargoTool = CargoTool {
    program: "flip-link",
    krate: "flip-link",
    version: "0.1.12",
};

/// Cargo's install root: `$CARGO_INSTALL_ROOT`, else `$CARGO_HOME`, else `~/.cargo` (its `bin/`
/// holds what `cargo install` installed).
pub fn cargo_install_root() -> Result<PathBuf> {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if let Some(root) = var("CARGO_INSTALL_ROOT").or_else(|| var("CARGO_HOME")) {
        return Ok(PathBuf::from(root));
    }
    let home = var("HOME").context("neither CARGO_INSTALL_ROOT, CARGO_HOME nor HOME is set")?;
    Ok(PathBuf::from(home).join(".cargo"))
}

/// Returns the path of `tool`: found on PATH, else in `bin/` of cargo's install root, else
/// installed there with `cargo install <crate> --version <version> --locked` (saying so on
/// stderr; it builds in `target/cargo-install` of `dir`, the workspace, so an install repeated
/// there does not build again). `cargo` runs in `dir`, with the toolchain of its
/// `rust-toolchain.toml`.
pub fn ensure_cargo_tool(tool: &CargoTool, dir: &Path) -> Result<PathBuf> {
    if let Some(p) = find_on_path(tool.program) {
        return Ok(p);
    }
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    ensure_cargo_tool_in(
        tool,
        Path::new(&cargo),
        &cargo_install_root()?,
        &dir.join("target").join("cargo-install"),
        dir,
    )
}

/// [`ensure_cargo_tool`] without the PATH look-up: `tool` in `root/bin`, installed there when
/// missing by `cargo` (run in `dir`, building in `build_dir`). Returns its path.
pub fn ensure_cargo_tool_in(
    tool: &CargoTool,
    cargo: &Path,
    root: &Path,
    build_dir: &Path,
    dir: &Path,
) -> Result<PathBuf> {
    let CargoTool {
        program,
        krate,
        version,
    } = *tool;
    let installed = root.join("bin").join(program);
    // One install at a time within this process (tests build in parallel): two installs into
    // two roots from one build folder failed to copy the program while the other replaced it.
    // Across processes cargo locks the install root and the build folder.
    static INSTALL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = INSTALL.lock().unwrap_or_else(|e| e.into_inner());
    if installed.is_file() {
        return Ok(installed);
    }
    eprintln!(
        "millac: `{program}` is missing, running `cargo install {krate} --version {version} \
         --locked --root {}`",
        root.display()
    );
    let status = Command::new(cargo)
        .args(["install", krate, "--version", version, "--locked", "--root"])
        .arg(root)
        .current_dir(dir)
        .env("CARGO_TARGET_DIR", build_dir)
        // What the cargo that runs us set for its own build is not for this one.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .status()
        .with_context(|| format!("running `{} install {krate}`", cargo.display()))?;
    if !status.success() {
        bail!(
            "`{program}` is missing and `cargo install {krate} --version {version} --locked --root {}` \
             failed ({status})",
            root.display()
        );
    }
    if !installed.is_file() {
        bail!(
            "`cargo install {krate}` succeeded but {} is missing",
            installed.display()
        );
    }
    Ok(installed)
}

/// The third-party grbl sender the end-to-end tests drive `serve` with: pygrbl-streamer 1.0.5
/// (PyPI; it streams with character counting against grbl's 128-byte buffer) and pyserial, in a
/// virtual environment under `dir` that is created (once) with `python3 -m venv` and pip. Returns
/// the environment's python.
pub fn ensure_python_sender(dir: &Path) -> Result<PathBuf> {
    python_env(
        dir,
        "pygrbl-streamer 1.0.5",
        "import pygrbl_streamer, serial",
        &[&["pygrbl-streamer==1.0.5", "pyserial"]],
    )
}

/// The bCNC sender (PyPI bCNC 0.9.16: its own Sender, G-code compiler and grbl 1.1 controller,
/// driven headless by `qemu/senders/bcnc_stream.py`) in a virtual environment under `dir`:
/// bCNC without its GUI-only dependencies (OpenCV, Pillow), with the three its non-GUI classes
/// import (pyserial, numpy, svgelements). Its modules import tkinter, so the system Python needs
/// Tk (Debian: python3-tk, installed as root when missing; no display is used). Returns the
/// environment's python.
pub fn ensure_bcnc(dir: &Path) -> Result<PathBuf> {
    let sys = find_on_path("python3").context("python3 not found on PATH")?;
    let tk = || {
        Command::new(&sys)
            .args(["-c", "import tkinter"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    };
    if !tk() {
        static INSTALL: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let _guard = INSTALL.lock().unwrap_or_else(|e| e.into_inner());
        if !tk() {
            if !is_root() {
                bail!("bCNC needs Python's tkinter: install it with `sudo apt-get install -y python3-tk`");
            }
            apt_install("python3-tk").context("bCNC needs Python's tkinter")?;
        }
    }
    python_env(
        dir,
        "bCNC 0.9.16",
        "import tkinter, serial, numpy, svgelements, importlib.util; \
         assert importlib.util.find_spec('bCNC')",
        &[
            &["--no-deps", "bCNC==0.9.16"],
            &["pyserial", "numpy", "svgelements"],
        ],
    )
}

/// A virtual environment under `dir` (`label` in messages) in which `check` (Python source)
/// runs: created once with `python3 -m venv` and the `pip install` steps. Returns its python.
fn python_env(dir: &Path, label: &str, check: &str, steps: &[&[&str]]) -> Result<PathBuf> {
    let python = dir.join("bin").join("python");
    let has = |py: &Path| {
        Command::new(py)
            .args(["-c", check])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    };
    if has(&python) {
        return Ok(python);
    }
    static INSTALL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = INSTALL.lock().unwrap_or_else(|e| e.into_inner());
    if has(&python) {
        return Ok(python);
    }
    let sys = find_on_path("python3").context("python3 not found on PATH")?;
    eprintln!(
        "millac: creating a Python environment in {} with {label}",
        dir.display()
    );
    let ok = Command::new(&sys)
        .args(["-m", "venv"])
        .arg(dir)
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if !ok {
        bail!(
            "`python3 -m venv {}` failed (Debian: apt-get install python3-venv)",
            dir.display()
        );
    }
    for step in steps {
        let ok = Command::new(&python)
            .args(["-m", "pip", "install", "-q"])
            .args(*step)
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
        if !ok {
            bail!(
                "`pip install {}` into {} failed",
                step.join(" "),
                dir.display()
            );
        }
    }
    if !has(&python) {
        bail!(
            "installed {label} into {} but `{check}` fails",
            dir.display()
        );
    }
    Ok(python)
}

/// LinuxCNC's standalone G-code interpreter `rs274` (it prints a program's canonical machining
/// calls), extracted from Debian packages, not installed: run [`Rs274::program`] with
/// `LD_LIBRARY_PATH` set to [`Rs274::library_path`].
#[derive(Clone, Debug)]
pub struct Rs274 {
    /// The `rs274` executable (`usr/bin/rs274` of the extracted tree).
    pub program: PathBuf,
    /// `LD_LIBRARY_PATH` for it: the extracted tree's `usr/lib` and `usr/lib/x86_64-linux-gnu`.
    pub library_path: std::ffi::OsString,
    /// The extracted tree's root (`usr/share/linuxcnc/ncfiles` holds LinuxCNC's example programs).
    pub root: PathBuf,
}

/// The Debian packages [`ensure_rs274`] extracts: the interpreter and the one library it needs that
/// a plain Debian 12 lacks.
pub const RS274_PACKAGES: [&str; 2] = ["linuxcnc-uspace", "libboost-python1.74.0"];

/// Returns a runnable `rs274` extracted under `dir` (the workspace's `target/rs274`). When `dir`
/// has no extracted tree yet, downloads [`RS274_PACKAGES`] there with `apt-get download` (no
/// install, root not needed; as root, `apt-get update` first when the download fails) and unpacks
/// them with `dpkg-deb -x` into `dir/lcnc`. Once per process (tests run in parallel).
pub fn ensure_rs274(dir: &Path) -> Result<Rs274> {
    let root = dir.join("lcnc");
    let rs274 = Rs274 {
        program: root.join("usr/bin/rs274"),
        library_path: std::env::join_paths([
            root.join("usr/lib"),
            root.join("usr/lib/x86_64-linux-gnu"),
        ])
        .context("LD_LIBRARY_PATH for rs274")?,
        root: root.clone(),
    };
    // The tree is complete when this marker exists (written after both packages are unpacked).
    let done = dir.join("extracted");
    static EXTRACT: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = EXTRACT.lock().unwrap_or_else(|e| e.into_inner());
    if done.is_file() && rs274.program.is_file() {
        return Ok(rs274);
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let packages = RS274_PACKAGES.join(" ");
    let what = format!(
        "`cd {} && apt-get download {packages}` (then `apt-get update` and again if the package \
         lists are missing)",
        dir.display()
    );
    let debs = |dir: &Path| -> Vec<PathBuf> {
        RS274_PACKAGES
            .iter()
            .filter_map(|p| {
                std::fs::read_dir(dir)
                    .ok()?
                    .flatten()
                    .map(|e| e.path())
                    .find(|f| {
                        f.file_name()
                            .and_then(|n| n.to_str())
                            .is_some_and(|n| n.starts_with(&format!("{p}_")) && n.ends_with(".deb"))
                    })
            })
            .collect()
    };
    if debs(dir).len() < RS274_PACKAGES.len() {
        eprintln!(
            "millac: LinuxCNC's rs274 is missing, running `apt-get download {packages}` in {}",
            dir.display()
        );
        let download = || {
            Command::new("apt-get")
                .arg("download")
                .args(RS274_PACKAGES)
                .current_dir(dir)
                .status()
                .map(|s| s.success())
                .unwrap_or(false)
        };
        let mut ok = download();
        if !ok && is_root() {
            let updated = Command::new("apt-get")
                .args(["-o", "DPkg::Lock::Timeout=300", "update"])
                .status();
            ok = matches!(updated, Ok(s) if s.success()) && download();
        }
        if !ok || debs(dir).len() < RS274_PACKAGES.len() {
            bail!(
                "LinuxCNC's rs274 is missing and `apt-get download {packages}` failed: run {what}"
            );
        }
    }
    for deb in debs(dir) {
        let status = Command::new("dpkg-deb")
            .arg("-x")
            .arg(&deb)
            .arg(&root)
            .status()
            .with_context(|| format!("running `dpkg-deb -x {}` (Debian: dpkg)", deb.display()))?;
        if !status.success() {
            bail!(
                "`dpkg-deb -x {} {}` failed ({status})",
                deb.display(),
                root.display()
            );
        }
    }
    if !rs274.program.is_file() {
        bail!(
            "unpacked {packages} into {} but {} is missing",
            root.display(),
            rs274.program.display()
        );
    }
    std::fs::write(&done, b"").with_context(|| format!("writing {}", done.display()))?;
    Ok(rs274)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packages_and_unknown_tools() {
        assert_eq!(debian_package("qemu-system-arm"), Some("qemu-system-arm"));
        assert_eq!(debian_package("sigrok-cli"), Some("sigrok-cli"));
        assert_eq!(debian_package("gcc"), Some("gcc"));
        let e = ensure_tool("millac-no-such-tool").unwrap_err().to_string();
        assert!(e.contains("millac-no-such-tool"), "{e}");
        assert!(ensure_tool("sh").is_ok() || find_on_path("sh").is_none());
    }

    /// Writes an executable shell script at `path` from a child process, so that this process
    /// never holds the file open for writing: a test running in parallel that forks while we
    /// held it would pass our descriptor to its child until that child execs, and executing the
    /// script then fails with ETXTBSY ("Text file busy"; CI failed once on exactly that).
    fn write_script(path: &Path, body: &str) {
        use std::io::Write;
        let mut child = Command::new("sh")
            .args(["-c", "cat > \"$1\" && chmod 755 \"$1\"", "sh"])
            .arg(path)
            .stdin(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        stdin
            .write_all(format!("#!/bin/sh\n{body}").as_bytes())
            .unwrap();
        drop(stdin);
        assert!(
            child.wait().unwrap().success(),
            "writing {}",
            path.display()
        );
    }

    #[test]
    fn scripts_run_at_once_while_other_threads_fork() {
        let dir = std::env::temp_dir().join(format!("millac-tools-{}-busy", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let forkers: Vec<_> = (0..2)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        let _ = Command::new("true").status();
                    }
                })
            })
            .collect();
        let mut busy = 0;
        for i in 0..200 {
            let p = dir.join(format!("s{i}"));
            write_script(&p, "exit 0\n");
            match Command::new(&p).status() {
                Ok(s) => assert!(s.success()),
                Err(e) => {
                    busy += 1;
                    eprintln!("{}: {e}", p.display());
                }
            }
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for f in forkers {
            f.join().unwrap();
        }
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(busy, 0, "scripts that could not be executed at once");
    }

    /// A scratch directory with a fake `rustc` that prints `sysroot` for `--print sysroot` and
    /// a fake `rustup` that appends its arguments to `rustup.log` and installs the target dir.
    fn fake_toolchain(name: &str) -> (PathBuf, PathBuf, PathBuf, PathBuf) {
        let dir = std::env::temp_dir().join(format!("millac-tools-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let sysroot = dir.join("sysroot");
        std::fs::create_dir_all(sysroot.join("lib/rustlib/x86_64-unknown-linux-gnu")).unwrap();
        let log = dir.join("rustup.log");
        let script = |name: &str, body: String| {
            let p = dir.join(name);
            write_script(&p, &body);
            p
        };
        let rustc = script(
            "rustc",
            format!(
                "[ \"$1 $2\" = \"--print sysroot\" ] || exit 3\necho '{}'\n",
                sysroot.display()
            ),
        );
        let rustup = script(
            "rustup",
            format!(
                "echo \"$@\" >> '{}'\n[ \"$1 $2\" = \"target add\" ] && mkdir -p '{}/lib/rustlib/'\"$3\"\n",
                log.display(),
                sysroot.display()
            ),
        );
        (dir, rustc, rustup, log)
    }

    #[test]
    fn adds_a_missing_rust_target_with_rustup_and_only_then() {
        let (dir, rustc, rustup, log) = fake_toolchain("add");
        let installed =
            ensure_rust_target_with("thumbv7m-none-eabi", &rustc, Some(&rustup), &dir).unwrap();
        assert!(installed);
        assert_eq!(
            std::fs::read_to_string(&log).unwrap(),
            "target add thumbv7m-none-eabi\n"
        );
        // Present now: rustup is not called again.
        let installed =
            ensure_rust_target_with("thumbv7m-none-eabi", &rustc, Some(&rustup), &dir).unwrap();
        assert!(!installed);
        assert_eq!(
            std::fs::read_to_string(&log).unwrap(),
            "target add thumbv7m-none-eabi\n"
        );
    }

    #[test]
    fn a_missing_target_without_rustup_names_the_command() {
        let (dir, rustc, _, log) = fake_toolchain("no-rustup");
        let e = ensure_rust_target_with("thumbv7m-none-eabi", &rustc, None, &dir)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rustup target add thumbv7m-none-eabi"), "{e}");
        assert!(!log.exists());
        // A present target needs no rustup at all.
        let e = ensure_rust_target_with("x86_64-unknown-linux-gnu", &rustc, None, &dir);
        assert!(!e.unwrap());
    }

    #[test]
    fn a_rustup_that_does_not_install_is_an_error() {
        let (dir, rustc, _, _) = fake_toolchain("false");
        let e = ensure_rust_target_with(
            "thumbv7m-none-eabi",
            &rustc,
            Some(Path::new("/bin/true")),
            &dir,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("thumbv7m-none-eabi"), "{e}");
    }
}
