//! Writes `sahkd.pc` beside the built library (target/<profile>/), so that
//! `PKG_CONFIG_PATH=target/release pkg-config --cflags --libs sahkd` finds the checked-in
//! header and the library of this build.

use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    // OUT_DIR is <target>/<profile>/build/<package>-<hash>/out.
    let Some(libdir) = out.ancestors().nth(3) else {
        return;
    };
    let pc = format!(
        "includedir={}\nlibdir={}\n\nName: sahkd\nDescription: SAH kd-trees for ray tracing (C API)\n\
         Version: {}\nCflags: -I${{includedir}}\nLibs: -L${{libdir}} -lsahkd\n\
         Libs.private: -lpthread -ldl -lm\n",
        manifest.join("include").display(),
        libdir.display(),
        std::env::var("CARGO_PKG_VERSION").unwrap(),
    );
    // Not fatal: a read-only target directory only loses the convenience.
    let _ = std::fs::write(libdir.join("sahkd.pc"), pc);
    println!("cargo:rerun-if-changed=build.rs");
}
