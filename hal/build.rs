//! Links the QEMU app with defmt's linker script (`defmt.x`, from defmt's build script): the
//! `.defmt` section that holds the log's format strings. For that binary only: the Nucleo board
//! is another package with its own link arguments, and the library links nothing.
fn main() {
    if std::env::var_os("CARGO_FEATURE_LM3S6965").is_some() {
        println!("cargo:rustc-link-arg-bin=millac-lm3s6965=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
