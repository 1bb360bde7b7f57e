//! The QEMU TCG plugin shared object, compiled from `qemu/plugin/millac_plugin.c` by build.rs and
//! embedded in the binary (host). Supports QEMU 7.x (plugin API version 1, tested on Debian's 7.2).
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// The plugin's bytes (a Linux shared object for the host).
pub const PLUGIN_SO: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/millac_plugin.so"));

/// File name used by [`write_plugin`].
pub const PLUGIN_FILE_NAME: &str = "millac_plugin.so";

/// Writes the embedded plugin into `dir` (created if needed) and returns its path.
pub fn write_plugin(dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(PLUGIN_FILE_NAME);
    std::fs::write(&path, PLUGIN_SO).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}
