//! External tools the host tool needs (qemu-system-arm, sigrok-cli, a C compiler): find them on PATH
//! and, when running as root, install the missing ones with apt-get (host).
use anyhow::{bail, Context, Result};
use std::path::PathBuf;
use std::process::Command;

/// The Debian package that provides `program`, for the programs millac uses.
pub fn debian_package(program: &str) -> Option<&'static str> {
    match program {
        "qemu-system-arm" => Some("qemu-system-arm"),
        "sigrok-cli" => Some("sigrok-cli"),
        "cc" | "gcc" => Some("gcc"),
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
    let apt_install = || {
        Command::new("apt-get")
            .args(["-o", "DPkg::Lock::Timeout=300", "install", "-y", package])
            .env("DEBIAN_FRONTEND", "noninteractive")
            .status()
    };
    let ok = apt_install().map(|s| s.success()).unwrap_or(false);
    if !ok {
        let updated = Command::new("apt-get")
            .args(["-o", "DPkg::Lock::Timeout=300", "update"])
            .status();
        let ok = matches!(updated, Ok(s) if s.success())
            && apt_install().map(|s| s.success()).unwrap_or(false);
        if !ok {
            bail!("`{program}` missing and `apt-get install -y {package}` failed");
        }
    }
    find_on_path(program).with_context(|| {
        format!("installed package {package} but `{program}` is still not on PATH")
    })
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
}
