//! Build script of millac-lm3s6965 (host, at build time): puts the board's memory map (the
//! lm3s6965evb's, `memory.x` at the workspace root) where cortex-m-rt's link.x finds it and links
//! defmt's linker script (`defmt.x`, from defmt's build script: the `.defmt` section that holds
//! the log's format strings).
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), include_bytes!("../../memory.x")).expect("write memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bin=millac-lm3s6965=-Tdefmt.x");
    println!("cargo:rerun-if-changed=../../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
