//! include/sahkd.h is checked in so that C users need no Rust to read it; this test
//! regenerates it from the sources with cbindgen and fails when the two differ.
//! `SAHKD_BLESS=1 cargo test -p sahkd-c --test header` writes the fresh header instead.

use std::path::Path;

#[test]
fn checked_in_header_is_cbindgens_output() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).unwrap();
    let mut fresh = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen could not read the C API's sources")
        .write(&mut fresh);
    let fresh = String::from_utf8(fresh).unwrap();
    let path = crate_dir.join("include/sahkd.h");
    if std::env::var_os("SAHKD_BLESS").is_some() {
        std::fs::write(&path, &fresh).unwrap();
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == fresh,
        "{} differs from cbindgen's output for the current sources: run \
         SAHKD_BLESS=1 cargo test -p sahkd-c --test header and commit the header",
        path.display()
    );
}
