//! Builds the firmware from the workspace (host): the QEMU board (millac-hal for
//! thumbv7m-none-eabi, [`build`]) and the real boards ([`build_board`], e.g. [`NUCLEO_F446RE`] for
//! the CI checks of its size and its ISRs, and [`NUCLEO_F446RE_QEMU`] to run it under QEMU). A nested cargo with its own target directory, so it
//! never waits on the lock of the cargo that runs us; the thumb target is added with rustup first
//! when missing (see `tools::ensure_rust_target`).
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The target and binary of the QEMU board.
pub const TARGET: &str = "thumbv7m-none-eabi";
pub const BIN: &str = "millac-lm3s6965";

/// A firmware binary: its package, target and binary name.
#[derive(Clone, Copy, Debug)]
pub struct Board {
    pub package: &'static str,
    pub target: &'static str,
    pub bin: &'static str,
    /// Cargo features of the package (e.g. `qemu`).
    pub features: &'static [&'static str],
}

/// The QEMU board.
pub const LM3S6965: Board = Board {
    package: "millac-hal",
    target: TARGET,
    bin: BIN,
    features: &[],
};

/// The Nucleo-F446RE (links with flip-link, see .cargo/config.toml).
pub const NUCLEO_F446RE: Board = Board {
    package: "millac-nucleo-f446re",
    target: "thumbv7em-none-eabihf",
    bin: "millac-nucleo-f446re",
    features: &[],
};

/// The Nucleo-F446RE firmware built to run under QEMU's netduinoplus2 machine (its `qemu`
/// feature; see `millac_qemu::f446`).
pub const NUCLEO_F446RE_QEMU: Board = Board {
    features: &["qemu"],
    ..NUCLEO_F446RE
};

/// The workspace root (where Cargo.toml of `millac` lives).
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// Builds the QEMU firmware in release mode and returns the ELF path. Installs the target with
/// rustup first when the toolchain lacks it.
pub fn build() -> Result<PathBuf> {
    build_board(&LM3S6965)
}

/// Builds a board's firmware in release mode and returns the ELF path (one target directory per
/// board, so two tests building two boards do not wait on each other's lock).
pub fn build_board(board: &Board) -> Result<PathBuf> {
    let Board {
        package,
        target: tgt,
        bin,
        features,
    } = *board;
    let ws = workspace();
    crate::tools::ensure_rust_target(tgt, &ws)?;
    let target_dir = if package == LM3S6965.package {
        ws.join("target").join("firmware")
    } else if features.is_empty() {
        ws.join("target").join(format!("firmware-{bin}"))
    } else {
        ws.join("target")
            .join(format!("firmware-{bin}-{}", features.join("-")))
    };
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(&cargo)
        .current_dir(&ws)
        .args([
            "build",
            "--quiet",
            "--release",
            "-p",
            package,
            "--target",
            tgt,
            "--bin",
            bin,
        ])
        .args(if features.is_empty() {
            Vec::new()
        } else {
            vec!["--features".to_string(), features.join(",")]
        })
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
            format!("\nhint: install the target with `rustup target add {tgt}`")
        } else if err.contains("flip-link") {
            "\nhint: install the linker wrapper with `cargo install flip-link`".to_string()
        } else {
            String::new()
        };
        bail!("building the firmware failed:\n{err}{hint}");
    }
    let elf = target_dir.join(tgt).join("release").join(bin);
    if !elf.exists() {
        bail!("firmware ELF missing after build: {}", elf.display());
    }
    Ok(elf)
}
