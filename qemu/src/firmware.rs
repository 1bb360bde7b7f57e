//! Builds the QEMU firmware (millac-hal for thumbv7m-none-eabi) from the workspace (host). A nested
//! cargo with its own target directory, so it never waits on the lock of the cargo that runs us;
//! the thumb target is added with rustup first when missing (see `tools::ensure_rust_target`).
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The target and binary of the QEMU board.
pub const TARGET: &str = "thumbv7m-none-eabi";
pub const BIN: &str = "millac-lm3s6965";

/// The workspace root (where Cargo.toml of `millac` lives).
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// Builds the firmware in release mode and returns the ELF path. Installs the target with rustup
/// first when the toolchain lacks it.
pub fn build() -> Result<PathBuf> {
    let ws = workspace();
    crate::tools::ensure_rust_target(TARGET, &ws)?;
    let target_dir = ws.join("target").join("firmware");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(&cargo)
        .current_dir(&ws)
        .args([
            "build",
            "--quiet",
            "--release",
            "-p",
            "millac-hal",
            "--target",
            TARGET,
            "--bin",
            BIN,
        ])
        .env("CARGO_TARGET_DIR", &target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .output()
        .with_context(|| format!("running {cargo} to build the firmware"))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let hint = if err.contains("can't find crate for `core`")
            || err.contains("target may not be installed")
        {
            format!("\nhint: install the target with `rustup target add {TARGET}`")
        } else {
            String::new()
        };
        bail!("building the firmware failed:\n{err}{hint}");
    }
    let elf = target_dir.join(TARGET).join("release").join(BIN);
    if !elf.exists() {
        bail!("firmware ELF missing after build: {}", elf.display());
    }
    Ok(elf)
}
