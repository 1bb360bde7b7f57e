//! Builds the firmware from the workspace (host): the QEMU board (millac-lm3s6965 for
//! thumbv7m-none-eabi, [`build`]) and the real boards ([`build_board`], e.g. [`NUCLEO_F446RE`] for
//! the CI checks of its size and its ISRs, and [`NUCLEO_F446RE_QEMU`] to run it under QEMU). A
//! nested cargo with its own target directory, so it never waits on the lock of the cargo that
//! runs us. What a fresh toolchain lacks is installed first: the thumb target with rustup
//! (`tools::ensure_rust_target`), the real boards' linker wrapper flip-link with `cargo install`
//! (`tools::ensure_cargo_tool`).
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The target and binary of the QEMU board.
pub const TARGET: &str = "thumbv7m-none-eabi";
pub const BIN: &str = "millac-lm3s6965";

/// A firmware binary: its package (and the package's manifest), target and binary name.
#[derive(Clone, Copy, Debug)]
pub struct Board {
    pub package: &'static str,
    /// The package's Cargo.toml, from the workspace root (the Nucleo-F446RE is a workspace of its
    /// own, see Cargo.toml).
    pub manifest: &'static str,
    pub target: &'static str,
    pub bin: &'static str,
    /// Cargo features of the package (e.g. `qemu`).
    pub features: &'static [&'static str],
    /// The cargo profile it is built with (its ELF is under `target/<target>/<profile>/`):
    /// `firmware` (opt-level "s", .cargo/config.toml) for the LM3S6965's 256 KiB of flash,
    /// `release` for the boards with room.
    pub profile: &'static str,
    /// The board's memory map (`FLASH`'s `LENGTH` is the flash the program gets) and its size
    /// budgets (`flash_bytes`, `ram_bytes`), from the workspace root.
    pub memory_x: &'static str,
    pub budget: &'static str,
}

/// The QEMU board.
pub const LM3S6965: Board = Board {
    package: "millac-lm3s6965",
    manifest: "hal/lm3s6965/Cargo.toml",
    target: TARGET,
    bin: BIN,
    features: &[],
    profile: "firmware",
    memory_x: "memory.x",
    budget: "hal/lm3s6965/budget.txt",
};

/// The Nucleo-F446RE (links with flip-link, see .cargo/config.toml).
pub const NUCLEO_F446RE: Board = Board {
    package: "millac-nucleo-f446re",
    manifest: "hal/nucleo-f446re/Cargo.toml",
    target: "thumbv7em-none-eabihf",
    bin: "millac-nucleo-f446re",
    features: &[],
    profile: "release",
    memory_x: "hal/nucleo-f446re/memory.x",
    budget: "hal/nucleo-f446re/budget.txt",
};

/// The Nucleo-F446RE firmware built to run under QEMU's netduinoplus2 machine (its `qemu`
/// feature; see `millac_qemu::emulator::f446`).
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

/// Builds the QEMU firmware (its profile, see [`Board::profile`]) and returns the ELF path. Installs the target with
/// rustup first when the toolchain lacks it.
pub fn build() -> Result<PathBuf> {
    build_board(&LM3S6965)
}

/// Builds a board's firmware with its profile and returns the ELF path (one target directory per
/// board, so two tests building two boards do not wait on each other's lock). Installs first what
/// the toolchain lacks: the Rust target (rustup) and the target's linker wrapper (flip-link for
/// the real boards, see [`linker_of`]).
pub fn build_board(board: &Board) -> Result<PathBuf> {
    let ws = workspace();
    let linker = linker_of(board.target)
        .map(|tool| crate::emulator::tools::ensure_cargo_tool(tool, &ws))
        .transpose()?;
    let target_dir = if board.package == LM3S6965.package {
        ws.join("target").join("firmware")
    } else if board.features.is_empty() {
        ws.join("target").join(format!("firmware-{}", board.bin))
    } else {
        ws.join("target").join(format!(
            "firmware-{}-{}",
            board.bin,
            board.features.join("-")
        ))
    };
    build_board_in(board, &target_dir, linker.as_deref())
}

/// The program .cargo/config.toml names as the linker of `target` where it is not rustc's own:
/// flip-link for thumbv7em-none-eabihf (the real boards). [`build_board`] installs it when
/// missing.
pub fn linker_of(target: &str) -> Option<&'static crate::emulator::tools::CargoTool> {
    match target {
        "thumbv7em-none-eabihf" => Some(&crate::emulator::tools::FLIP_LINK),
        _ => None,
    }
}

/// [`build_board`] in `target_dir`, linked with `linker` (a path: cargo's
/// `CARGO_TARGET_<TRIPLE>_LINKER`, instead of the program .cargo/config.toml names for the target
/// and PATH finds). Adds the Rust target with rustup when missing.
pub fn build_board_in(board: &Board, target_dir: &Path, linker: Option<&Path>) -> Result<PathBuf> {
    let Board {
        package,
        manifest,
        target: tgt,
        bin,
        features,
        profile,
        ..
    } = *board;
    let ws = workspace();
    crate::emulator::tools::ensure_rust_target(tgt, &ws)?;
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut command = Command::new(&cargo);
    if let Some(linker) = linker {
        let var = format!(
            "CARGO_TARGET_{}_LINKER",
            tgt.to_uppercase().replace(['-', '.'], "_")
        );
        command.env(var, linker);
    }
    let out = command
        .current_dir(&ws)
        .args(["build", "--quiet", "--profile", profile, "--manifest-path"])
        .arg(ws.join(manifest))
        .args(["-p", package, "--target", tgt, "--bin", bin])
        .args(if features.is_empty() {
            Vec::new()
        } else {
            vec!["--features".to_string(), features.join(",")]
        })
        .env("CARGO_TARGET_DIR", target_dir)
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
        } else {
            String::new()
        };
        bail!("building the firmware failed:\n{err}{hint}");
    }
    let elf = target_dir.join(tgt).join(profile).join(bin);
    if !elf.exists() {
        bail!("firmware ELF missing after build: {}", elf.display());
    }
    Ok(elf)
}

impl Board {
    /// A `key = value` line of the board's budget file (comments start with `#`).
    pub fn budget(&self, key: &str) -> Result<u64> {
        let path = workspace().join(self.budget);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        let value = text
            .lines()
            .filter(|l| !l.trim_start().starts_with('#'))
            .filter_map(|l| l.split_once('='))
            .find(|(k, _)| k.trim() == key)
            .with_context(|| format!("{key} missing in {}", path.display()))?
            .1;
        value
            .trim()
            .parse()
            .with_context(|| format!("{key} in {}: {value:?}", path.display()))
    }

    /// The flash the program gets: `LENGTH` of the `FLASH` region of the board's memory.x (a
    /// number of bytes, or of KiB with `K`, MiB with `M`).
    pub fn flash_capacity(&self) -> Result<u64> {
        let path = workspace().join(self.memory_x);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with("FLASH"))
            .with_context(|| format!("no FLASH region in {}", path.display()))?;
        let length = line
            .split_once("LENGTH")
            .and_then(|(_, r)| r.split_once('='))
            .map(|(_, v)| v.trim().trim_end_matches(',').trim())
            .with_context(|| format!("no LENGTH in {line:?}"))?;
        let (digits, scale) = match length.as_bytes().last() {
            Some(b'K') => (&length[..length.len() - 1], 1024),
            Some(b'M') => (&length[..length.len() - 1], 1024 * 1024),
            _ => (length, 1),
        };
        let n: u64 = digits
            .trim()
            .parse()
            .with_context(|| format!("LENGTH {length:?} in {}", path.display()))?;
        Ok(n * scale)
    }

    /// The flash and static RAM the built image `elf` uses, checked against the board's budgets
    /// (and against an implausibly small image, which would say the measure is broken): the
    /// figures, or what exceeds. Both boards' budget tests call it.
    pub fn check_budgets(&self, elf: &Path) -> Result<crate::emulator::elf::MemoryUse> {
        let bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
        let m = crate::emulator::elf::memory_use_in(&bytes, 0x2000_0000)?;
        let (flash, ram) = (self.budget("flash_bytes")?, self.budget("ram_bytes")?);
        println!(
            "{}: flash {} of {flash} bytes, RAM {} of {ram} bytes",
            self.bin, m.flash, m.ram
        );
        anyhow::ensure!(
            m.flash > 16 * 1024,
            "flash {} is implausibly small",
            m.flash
        );
        anyhow::ensure!(m.flash <= flash, "flash {} > budget {flash}", m.flash);
        anyhow::ensure!(m.ram <= ram, "RAM {} > budget {ram}", m.ram);
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every board's flash budget leaves at least a quarter of its flash free (room for what the
    /// next features add), and its RAM budget is set.
    #[test]
    fn every_flash_budget_leaves_an_eighth_of_the_flash_free() {
        for board in [LM3S6965, NUCLEO_F446RE] {
            let capacity = board.flash_capacity().unwrap();
            let budget = board.budget("flash_bytes").unwrap();
            assert!(capacity >= 64 * 1024, "{}: {capacity}", board.bin);
            assert!(
                budget * 8 <= capacity * 7,
                "{}: flash budget {budget} of {capacity} bytes leaves less than 12.5 % free",
                board.bin
            );
            assert!(board.budget("ram_bytes").unwrap() > 0);
        }
    }

    /// `linker_of` names the linker .cargo/config.toml sets for each board's target (none: rustc's
    /// own), so that what `build_board` installs is what the build runs.
    #[test]
    fn the_linkers_installed_are_those_of_the_cargo_config() {
        let path = workspace().join(".cargo").join("config.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let mut section = String::new();
        let mut linkers = Vec::new();
        for line in text.lines().map(str::trim) {
            if line.starts_with('[') {
                section = line.trim_matches(['[', ']']).to_string();
            } else if let Some((key, value)) = line.split_once('=') {
                if key.trim() == "linker" {
                    let target = section.strip_prefix("target.").unwrap_or(&section);
                    linkers.push((
                        target.to_string(),
                        value.trim().trim_matches('"').to_string(),
                    ));
                }
            }
        }
        for board in [LM3S6965, NUCLEO_F446RE] {
            let configured = linkers
                .iter()
                .find(|(t, _)| t == board.target)
                .map(|(_, l)| l.as_str());
            assert_eq!(
                configured,
                linker_of(board.target).map(|t| t.program),
                "{}: the linker of {} in {}",
                board.package,
                board.target,
                path.display()
            );
        }
    }
}
