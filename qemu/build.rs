//! Build script of millac-qemu (host): compiles the QEMU TCG plugin `plugin/millac_plugin.c` with the
//! system C compiler into OUT_DIR so the binary can embed it (`include_bytes!`).
use std::env;
use std::path::PathBuf;
use std::process::Command;

fn main() {
    let src = "plugin/millac_plugin.c";
    println!("cargo:rerun-if-changed={src}");
    println!("cargo:rerun-if-env-changed=CC");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR")).join("millac_plugin.so");
    let candidates: Vec<String> = match env::var("CC") {
        Ok(cc) if !cc.is_empty() => vec![cc],
        _ => vec!["cc".into(), "gcc".into(), "clang".into()],
    };
    let mut tried = Vec::new();
    for cc in &candidates {
        let result = Command::new(cc)
            .args(["-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-o"])
            .arg(&out)
            .arg(src)
            .status();
        match result {
            Ok(s) if s.success() => return,
            Ok(s) => panic!("millac-qemu: compiling {src} with `{cc}` failed ({s})"),
            Err(e) => tried.push(format!("{cc}: {e}")),
        }
    }
    panic!(
        "millac-qemu: no C compiler found to build the QEMU plugin {src} (tried {}). \
         Install one, e.g. `apt-get install -y gcc`, or set CC.",
        tried.join("; ")
    );
}
