//! Byte-reproducible outputs: the same experiment run with 1 and with 2 threads
//! (reference included, each run with its own reference cache) writes byte-identical
//! EXR and PNG files — images, error images, signed block errors and the viewer's
//! radiance scripts — and a `cells.csv` equal apart from its timing columns (`*_s`)
//! and the thread count itself.

use photonlab::experiment::{RunArgs, run};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn manifest(threads: u32) -> String {
    format!(
        r#"
scene = "cornell-glass"
resolution = [64, 40]
[reference]
integrator = "path"
spp = 8
max_depth = 4
threads = {threads}
[base]
integrator = "photon"
spp = 2
photons = 4000
caustic_photons = 1000
gather_samples = 8
threads = {threads}
[sweep]
gather = ["direct", "irradiance_cache"]
repeats = 2
"#
    )
}

/// Every file under `dir` (relative path → bytes).
fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// cells.csv without the columns that may differ: times and the thread count.
fn stable_csv(path: &Path) -> Vec<Vec<String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header: Vec<String> = r.headers().unwrap().iter().map(str::to_string).collect();
    let keep: Vec<usize> =
        (0..header.len()).filter(|&i| !header[i].ends_with("_s") && header[i] != "threads" && header[i] != "cfg_threads").collect();
    let mut rows = vec![keep.iter().map(|&i| header[i].clone()).collect::<Vec<_>>()];
    for rec in r.records() {
        let rec = rec.unwrap();
        rows.push(keep.iter().map(|&i| rec[i].to_string()).collect());
    }
    rows
}

#[test]
fn one_and_two_threads_write_identical_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let mut outs = Vec::new();
    for threads in [1, 2] {
        let d = root.join(format!("t{threads}"));
        std::fs::create_dir_all(&d).unwrap();
        let m = d.join("repro.toml");
        std::fs::write(&m, manifest(threads)).unwrap();
        let out = d.join("repro");
        let r = run(&RunArgs::quiet(m, out.clone())).unwrap();
        assert!(r.reference_rendered && r.finalized);
        outs.push(out);
    }
    let (a, b) = (files(&outs[0]), files(&outs[1]));
    let images = |f: &BTreeMap<PathBuf, Vec<u8>>| -> Vec<PathBuf> {
        f.keys()
            .filter(|p| {
                let s = p.to_string_lossy();
                (s.starts_with("cells/") || s.starts_with("view/") || s.starts_with("reference-"))
                    && (s.ends_with(".exr") || s.ends_with(".png") || s.ends_with(".js"))
            })
            .cloned()
            .collect()
    };
    let names = images(&a);
    assert_eq!(names, images(&b));
    // 4 cells × (exr, png, relerr, signed) + reference exr/png + 5 viewer scripts.
    assert_eq!(names.len(), 4 * 4 + 2 + 5, "{names:?}");
    for n in &names {
        assert!(a[n] == b[n], "{} differs between 1 and 2 threads", n.display());
    }
    assert_eq!(stable_csv(&outs[0].join("cells.csv")), stable_csv(&outs[1].join("cells.csv")));
    std::fs::remove_dir_all(root).ok();
}
