//! `photonlab._photonlab`: the Rust half of the Python package. The pure-Python
//! wrappers in `python/photonlab/` turn keyword arguments into the command line's
//! `KEY=VALUE` text and bytes into numpy arrays; everything here goes through the same
//! library calls as the CLI (`RenderArgs::config`, `pipeline::render_scene_observed`,
//! `experiment::run`), so the pixels and the files are the CLI's.
//!
//! Renders run on a worker thread with the GIL released; the calling thread waits in
//! short slices and checks for signals between them, so Ctrl-C raises
//! `KeyboardInterrupt` after `photonlab::progress::cancel` has stopped the render.

use photonlab::cli::RenderArgs;
use photonlab::experiment::{self, RunArgs, Shard};
use photonlab::film::Film;
use photonlab::math::Color;
use photonlab::param::ParamDef;
use pyo3::exceptions::{PyFileNotFoundError, PyKeyboardInterrupt, PyOSError, PyPermissionError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyByteArray;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

/// An error of the library as the CLI prints it (contexts joined, outermost first),
/// raised as `OSError` when a file could not be read or written, as
/// `KeyboardInterrupt` when the render was cancelled, else as `ValueError`.
fn py_err(e: anyhow::Error) -> PyErr {
    let msg = e.chain().map(|c| c.to_string()).collect::<Vec<_>>().join(": ");
    if e.chain().any(|c| c.is::<photonlab::progress::Interrupted>()) {
        PyKeyboardInterrupt::new_err(msg)
    } else if let Some(io) = e.chain().find_map(|c| c.downcast_ref::<std::io::Error>()) {
        match io.kind() {
            std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(msg),
            std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(msg),
            _ => PyOSError::new_err(msg),
        }
    } else {
        PyValueError::new_err(msg)
    }
}

/// Runs `work` on a thread of its own with the GIL released, checking for signals
/// (Ctrl-C) every 50 ms; on one, cancels the render, waits for it to stop and raises.
fn interruptible<T: Send + 'static>(py: Python<'_>, work: impl FnOnce() -> anyhow::Result<T> + Send + 'static) -> PyResult<T> {
    let (tx, mut rx) = mpsc::channel();
    let handle = std::thread::spawn(move || {
        let _ = tx.send(work());
    });
    loop {
        let (got, back) = py.detach(move || (rx.recv_timeout(Duration::from_millis(50)), rx));
        rx = back;
        match got {
            Ok(result) => {
                let _ = handle.join();
                return result.map_err(py_err);
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                // The worker panicked: report it instead of hanging.
                let why = handle
                    .join()
                    .err()
                    .and_then(|p| p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())));
                return Err(pyo3::exceptions::PyRuntimeError::new_err(format!("photonlab panicked: {}", why.unwrap_or_default())));
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if let Err(signal) = py.check_signals() {
            photonlab::progress::cancel();
            let _ = py.detach(move || rx.recv());
            let _ = handle.join();
            photonlab::progress::clear_cancel();
            return Err(signal);
        }
    }
}

/// Checks that `path` can be opened, so a missing file is an `OSError` carrying the
/// system's error (the loaders fold it into their message): "PATH: cannot read WHAT:
/// No such file or directory (os error 2)", as the CLI says it.
fn readable(path: &std::path::Path, what: &str) -> anyhow::Result<()> {
    std::fs::File::open(path).map(drop).map_err(|e| anyhow::Error::new(e).context(format!("{}: cannot read {what}", path.display())))
}

/// Linear RGB float32, row-major from the top-left pixel, as bytes (numpy reads them
/// with `frombuffer(...).reshape(h, w, 3)`).
fn film_bytes<'py>(py: Python<'py>, f: &Film) -> Bound<'py, PyByteArray> {
    let mut bytes = Vec::with_capacity(f.pixels.len() * 12);
    for p in &f.pixels {
        for v in p.to_array() {
            bytes.extend_from_slice(&v.to_ne_bytes());
        }
    }
    PyByteArray::new(py, &bytes)
}

/// A film from float32 RGB bytes (native order) of a `width` × `height` image.
fn film_from(width: u32, height: u32, bytes: &[u8], what: &str) -> PyResult<Film> {
    let n = width as usize * height as usize;
    if bytes.len() != n * 12 {
        return Err(PyValueError::new_err(format!(
            "{what}: {} bytes for a {width}x{height} RGB float32 image (expected {})",
            bytes.len(),
            n * 12
        )));
    }
    let f = |i: usize| f32::from_ne_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let pixels = (0..n).map(|p| Color::new(f(p * 12), f(p * 12 + 4), f(p * 12 + 8))).collect();
    Ok(Film { width, height, pixels })
}

type Image<'py> = (u32, u32, Bound<'py, PyByteArray>);

/// Renders like `photonlab render`: `params` are (key, command-line text) pairs set
/// as `--set KEY=VALUE`. Returns the image, the requested AOVs and the run's figures
/// (JSON: timings, rays, integrator counters).
#[pyfunction]
#[pyo3(signature = (scene, builtin, params, aovs, progress))]
#[allow(clippy::type_complexity)]
fn render<'py>(
    py: Python<'py>,
    scene: Option<PathBuf>,
    builtin: Option<String>,
    params: Vec<(String, String)>,
    aovs: Vec<String>,
    progress: bool,
) -> PyResult<(Image<'py>, Vec<(String, Image<'py>)>, String)> {
    let (film, aovs, info) = interruptible(py, move || {
        let mut args = RenderArgs {
            scene,
            builtin,
            integrator: None,
            spp: None,
            sampler: None,
            accel: None,
            rr: None,
            max_depth: None,
            seed: None,
            threads: None,
            resolution: None,
            set: params.iter().map(|(k, v)| format!("{k}={v}")).collect(),
            aov: aovs,
            sample_range: None,
            output: None,
            quiet: !progress,
        };
        if args.scene.is_some() && args.builtin.is_some() {
            anyhow::bail!("give either scene or builtin, not both");
        }
        let cfg = args.config()?;
        photonlab::registry::validate(&cfg)?;
        if let Some(p) = &args.scene {
            readable(p, "scene file")?;
        }
        let scene = args.load()?;
        for w in &scene.warnings {
            if progress {
                eprintln!("warning: {w}");
            }
        }
        let o = photonlab::pipeline::render_scene_observed(scene, &cfg, args.quiet, &std::mem::take(&mut args.aov), &mut |_, _, _| {})?;
        let rays = o.rays();
        let info = serde_json::json!({
            "timings": o.timings,
            "threads": o.threads,
            "rays": rays.total_rays(),
            "camera_rays": rays.rays,
            "shadow_rays": rays.shadow_rays,
            "nonfinite_samples": o.stats.nonfinite_samples,
            "accel_bytes": o.accel_bytes,
            "extra": o.extra,
            "config": cfg,
        });
        Ok((o.film, o.aovs, info.to_string()))
    })?;
    let image = |f: &Film| (f.width, f.height, film_bytes(py, f));
    Ok((image(&film), aovs.iter().map(|(n, f)| (n.clone(), image(f))).collect(), info))
}

/// Runs a manifest like `photonlab run`; returns (experiment directory, cells.csv
/// text, cells rendered now, cells kept, whether the tables were written). For one
/// shard of several the CSV holds that shard's finished cells (no bias/variance split,
/// which needs every repeat: `photonlab merge` writes it).
#[pyfunction]
#[pyo3(signature = (manifest, out, force, shard, progress))]
fn run(
    py: Python<'_>,
    manifest: PathBuf,
    out: Option<PathBuf>,
    force: bool,
    shard: Option<String>,
    progress: bool,
) -> PyResult<(String, String, usize, usize, bool)> {
    let shard: Option<Shard> = shard.map(|s| s.parse().map_err(PyValueError::new_err)).transpose()?;
    interruptible(py, move || {
        readable(&manifest, "manifest")?;
        let args = RunArgs { manifest, out, force, shard, reference_only: false, list: false, quiet: !progress };
        let r = experiment::run(&args)?;
        let csv = if r.finalized {
            let p = r.dir.join("cells.csv");
            std::fs::read_to_string(&p).map_err(|e| anyhow::Error::new(e).context(format!("{}: cannot read", p.display())))?
        } else {
            let rows = experiment::finished_rows(&r.dir, shard)?;
            String::from_utf8(experiment::output::csv_bytes(&rows)?)?
        };
        Ok((r.dir.display().to_string(), csv, r.ran, r.kept, r.finalized))
    })
}

fn param_json(d: &ParamDef) -> serde_json::Value {
    serde_json::json!({"name": d.name, "type": d.ty, "default": d.default, "doc": d.doc})
}

/// The catalogue of `photonlab plugins` as JSON: common keys, families with their
/// plug-ins and parameters, shared parameter groups.
#[pyfunction]
fn plugins() -> String {
    let cat = photonlab::registry::catalogue();
    let families: Vec<serde_json::Value> = cat
        .families
        .iter()
        .map(|f| {
            let plugins: Vec<serde_json::Value> = f
                .plugins
                .iter()
                .map(|p| {
                    serde_json::json!({
                        "name": p.name, "doc": p.doc, "groups": p.groups,
                        "params": p.params.iter().map(param_json).collect::<Vec<_>>(),
                    })
                })
                .collect();
            serde_json::json!({"key": f.key, "doc": f.doc, "plugins": plugins})
        })
        .collect();
    let groups: Vec<serde_json::Value> = cat
        .groups
        .iter()
        .map(|g| serde_json::json!({"name": g.name, "doc": g.doc, "params": g.params.iter().map(param_json).collect::<Vec<_>>()}))
        .collect();
    serde_json::json!({
        "common": cat.common.iter().map(param_json).collect::<Vec<_>>(),
        "families": families,
        "groups": groups,
    })
    .to_string()
}

/// `photonlab plugins --markdown`.
#[pyfunction]
fn plugins_markdown() -> String {
    photonlab::registry::catalogue().markdown()
}

/// The figures of `photonlab diff --block BLOCK` and of the experiment runner's
/// cells, as JSON.
#[pyfunction]
fn diff(width: u32, height: u32, img: &[u8], reference: &[u8], block: u32) -> PyResult<String> {
    let a = film_from(width, height, img, "img")?;
    let b = film_from(width, height, reference, "ref")?;
    let e = experiment::cell::error_metrics(&a, &b).map_err(py_err)?;
    let r = experiment::metrics::robust_metrics(&a, &b).map_err(py_err)?;
    let blocks = photonlab::compare::compare_blocks(&a, &b, block, experiment::metrics::BLOCK_MIN_REF).map_err(py_err)?;
    let worst = blocks.worst().map(|w| {
        serde_json::json!({
            "x": w.at.0 * block, "y": w.at.1 * block, "test": w.test, "reference": w.reference,
            "rel": w.rel(), "std_err": w.std_err,
        })
    });
    Ok(serde_json::json!({
        "mean_test": a.mean().to_array(),
        "mean_reference": b.mean().to_array(),
        "rmse": e.rmse,
        "mse": e.mse,
        "relmse": e.relmse,
        "mae": e.mae,
        "relmse_trimmed": r.relmse_trimmed,
        "smape": r.smape,
        "max_pixel_share": r.max_pixel_share,
        "block": block,
        "mean_ratio": blocks.mean_ratio,
        "blocks_judged": blocks.blocks.len(),
        "worst_block": worst,
    })
    .to_string())
}

/// Reads an EXR as (width, height, float32 RGB bytes).
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Image<'py>> {
    readable(&path, "image").map_err(py_err)?;
    let f = Film::read_exr(&path).map_err(py_err)?;
    Ok((f.width, f.height, film_bytes(py, &f)))
}

/// The built-in scene names.
#[pyfunction]
fn builtins() -> Vec<&'static str> {
    photonlab::scene::builtin::BUILTINS.to_vec()
}

/// The Rust half of the `photonlab` package.
#[pymodule]
fn _photonlab(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(plugins, m)?)?;
    m.add_function(wrap_pyfunction!(plugins_markdown, m)?)?;
    m.add_function(wrap_pyfunction!(diff, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(builtins, m)?)?;
    Ok(())
}
