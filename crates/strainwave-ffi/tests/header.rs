//! `include/strainwave.h` is what cbindgen generates from this crate now.

use std::path::Path;

#[test]
fn header_is_current() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen could not read the crate");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let path = crate_dir.join("../../include/strainwave.h");
    if std::env::var_os("SW_UPDATE_HEADER").is_some() {
        std::fs::write(&path, &generated).expect("writing include/strainwave.h");
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "include/strainwave.h is stale; regenerate it with\n    \
         SW_UPDATE_HEADER=1 cargo test -p strainwave-ffi --test header\nand commit it"
    );
}
