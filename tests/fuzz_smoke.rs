//! A short run of the reader fuzzer (`photonlab fuzz`; the README gives the 10^5-input
//! run): mutated scene TOML, OBJ, MTL and manifests end in `Ok` or an error, never a
//! panic; and the hang it found (a manifest expanding to 10^8 cells) is an error.

use photonlab::experiment::manifest::Manifest;
use photonlab::fuzz::{FuzzArgs, fuzz};
use std::path::Path;

#[test]
fn mutated_inputs_never_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().to_path_buf();
    let r = fuzz(&FuzzArgs { inputs: 4000, seed: 7, corpus: vec![], out: out.clone(), timeout: 60 }).unwrap();
    assert_eq!(r.inputs, 4000);
    assert!(r.panics.is_empty(), "panics: {:?}", r.panics);
    // Both outcomes occur: the mutations are neither all fatal nor all harmless.
    assert!(r.ok > 100 && r.errors > 1000, "ok {} errors {}", r.ok, r.errors);
    std::fs::remove_dir_all(out).ok();
}

#[test]
fn a_manifest_of_too_many_cells_is_an_error() {
    let text = "scene = \"cornell\"\nresolution = [8, 8]\n[reference]\nspp = 1\n[sweep]\nspp = [1, 2]\nrepeats = 99999999\n";
    let e = Manifest::parse(text, Path::new("big.toml"), Path::new(".")).unwrap_err().to_string();
    assert!(e.contains("big.toml:7") && e.contains("100000 cells"), "{e}");
}
