//! `bench embree-compare`: runs the Embree reference harness (a C program over
//! Debian's Embree 3, not part of the repository: `--harness-dir DIR` or
//! `PHOTONLAB_EMBREE_DIR` names its folder) and `bench accel` on the same OBJ files with
//! the same ray definitions, case by case and back to back (so both see the same
//! machine load), and prints photonlab/Embree throughput ratios per ray set.
//!
//! Cases: the Stanford dragon and Dabrovic Sponza from `--scenes` (when present; see
//! docs/experiments.md for the downloads) and the built-in displaced sphere (≥ 1 M
//! triangles) exported as OBJ,
//! each with the outside and the inside camera, at each thread count.

use super::accel::{BenchMesh, BenchRow, TraceOpts, run_mesh};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Flags of `bench embree-compare`.
#[derive(Args, Debug, Clone)]
pub struct EmbreeArgs {
    /// The harness binary (default: `embree_bench` in --harness-dir, else a copy built
    /// under --work-dir from the sources there, else one built there before).
    #[arg(long)]
    pub harness: Option<PathBuf>,
    /// Folder with the harness sources (`embree_bench.c`, `build.sh`); default: the
    /// environment variable PHOTONLAB_EMBREE_DIR. The harness is not part of the
    /// repository (docs/benchmarks.md says where it comes from).
    #[arg(long, visible_alias = "embree-dir")]
    pub harness_dir: Option<PathBuf>,
    /// Folder with `stanford-dragon/dragon.obj` and `sponza-dabrovic/sponza.obj`
    /// (missing models are skipped; docs/experiments.md lists the downloads).
    #[arg(long, default_value = "../shared/scenes")]
    pub scenes: PathBuf,
    /// Where the built-in sphere is exported (and the harness built if needed).
    #[arg(long, default_value = "target/embree-harness")]
    pub work_dir: PathBuf,
    /// Rays per set.
    #[arg(long, default_value_t = 2_000_000)]
    pub rays: usize,
    /// Thread counts, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub threads: Vec<usize>,
    /// photonlab accelerators, comma-separated (each gets its own ratio).
    #[arg(long, value_delimiter = ',', default_value = "bvh8")]
    pub accel: Vec<String>,
    /// Only these cases (dragon, dragon-inside, sponza, sponza-inside,
    /// displaced-sphere, displaced-sphere-inside), comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub cases: Vec<String>,
    /// Runs per case and engine, alternating between the engines; each engine's best
    /// run gives `ratio` (on a shared machine the best run is the least disturbed
    /// one), and the median of the back-to-back pairs' ratios is printed beside it.
    #[arg(long, default_value_t = 1)]
    pub repeats: usize,
    /// Print JSON lines (both engines' figures and the ratio) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also trace the diffuse rays as a stream with this many in flight (`bench accel
    /// --stream`), compared with the harness's 8-ray packets (`rtcIntersect8`).
    #[arg(long, default_value_t = 0)]
    pub stream: usize,
}

/// One compared row.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CompareRow {
    /// Scene name (with `-inside`).
    pub scene: String,
    /// `camera`, `diffuse` or `shadow`.
    pub rays: String,
    /// The queries compared, photonlab's / Embree's (`intersect1`, `occluded1`,
    /// `stream8/intersect8`).
    pub api: String,
    /// Threads.
    pub threads: usize,
    /// photonlab engine (`photonlab-<accel>`).
    pub engine: String,
    /// Embree Mrays/s.
    pub embree_mrays_per_s: f64,
    /// photonlab Mrays/s.
    pub photonlab_mrays_per_s: f64,
    /// photonlab / Embree, each engine's best run.
    pub ratio: f64,
    /// Median over the repeats of photonlab / Embree within one back-to-back pair
    /// of runs (robust to a disturbed run of either engine; equals `ratio` for one
    /// repeat).
    pub paired_median: f64,
    /// Lowest and highest of those paired ratios.
    pub paired_range: [f64; 2],
    /// Embree hit fraction.
    pub embree_hit_fraction: f64,
    /// photonlab hit fraction.
    pub photonlab_hit_fraction: f64,
    /// Embree build (HIGH quality), seconds.
    pub embree_build_s: f64,
    /// photonlab build, seconds.
    pub photonlab_build_s: f64,
}

/// How to get the harness, for the errors of [`locate_harness`].
const HOW_TO_GET: &str = "the Embree harness (embree_bench.c and build.sh, a C program over Debian's libembree-dev) is not \
     part of the repository: on the project's machines it is shared/bench/embree beside the clone; pass its folder with \
     --harness-dir DIR (or set PHOTONLAB_EMBREE_DIR), or a built binary with --harness PATH";

/// Finds the harness binary: `--harness`, else `embree_bench` in the harness folder,
/// else a private copy built under `--work-dir` from the sources there, else a copy
/// built there before.
fn locate_harness(a: &EmbreeArgs) -> Result<PathBuf> {
    if let Some(h) = &a.harness {
        if h.is_file() {
            return Ok(h.clone());
        }
        bail!("--harness {}: no such file", h.display());
    }
    let built = a.work_dir.join("embree_bench");
    let from_env = || std::env::var_os("PHOTONLAB_EMBREE_DIR").filter(|v| !v.is_empty()).map(PathBuf::from);
    let Some(dir) = &a.harness_dir.clone().or_else(from_env) else {
        if built.is_file() {
            return Ok(built);
        }
        bail!("no Embree harness given and none built in {}: {HOW_TO_GET}", a.work_dir.display());
    };
    if !dir.is_dir() {
        bail!("--harness-dir {}: no such folder ({HOW_TO_GET})", dir.display());
    }
    for cand in [dir.join("embree_bench"), built.clone()] {
        if cand.is_file() {
            return Ok(cand);
        }
    }
    let src = dir.join("embree_bench.c");
    if !src.is_file() {
        bail!("--harness-dir {}: no embree_bench.c there ({HOW_TO_GET})", dir.display());
    }
    let harness_dir = dir;
    // Build a copy: the shared folder stays untouched.
    std::fs::create_dir_all(&a.work_dir).with_context(|| format!("creating {}", a.work_dir.display()))?;
    for f in ["embree_bench.c", "build.sh"] {
        std::fs::copy(harness_dir.join(f), a.work_dir.join(f)).with_context(|| format!("copying {f} from {}", harness_dir.display()))?;
    }
    eprintln!("building the Embree harness in {} (build.sh installs libembree-dev if missing)", a.work_dir.display());
    let st = Command::new("bash").arg("build.sh").current_dir(&a.work_dir).status().context("running build.sh")?;
    let bin = a.work_dir.join("embree_bench");
    if !st.success() || !bin.is_file() {
        bail!("building the Embree harness failed ({st}); see the output above (it needs gcc and libembree-dev)");
    }
    Ok(bin)
}

/// Runs the harness on one case; returns its JSON rows.
fn run_harness(bin: &Path, obj: &Path, inside: bool, threads: usize, rays: usize) -> Result<Vec<serde_json::Value>> {
    let mut cmd = Command::new(bin);
    cmd.arg(obj).args(["--threads", &threads.to_string(), "--rays", &rays.to_string(), "--builds", "1"]);
    if inside {
        cmd.arg("--inside");
    }
    let out = cmd.output().with_context(|| format!("running {}", bin.display()))?;
    if !out.status.success() {
        bail!("{} failed on {}: {}", bin.display(), obj.display(), String::from_utf8_lossy(&out.stderr).trim());
    }
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).with_context(|| format!("harness output is not JSON: {l}")))
        .collect()
}

/// Runs `bench embree-compare`.
pub fn run(a: &EmbreeArgs) -> Result<()> {
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    if a.threads.is_empty() || a.threads.iter().any(|&t| t == 0 || t > 64) {
        bail!("--threads: give thread counts between 1 and 64");
    }
    let harness = locate_harness(a)?;
    std::fs::create_dir_all(&a.work_dir).with_context(|| format!("creating {}", a.work_dir.display()))?;
    let sphere = a.work_dir.join("displaced-sphere.obj");
    if !sphere.is_file() {
        eprintln!("exporting the built-in displaced sphere to {}", sphere.display());
        BenchMesh::from_builtin("displaced-sphere")?.write_obj(&sphere)?;
    }
    let files = [
        ("dragon", a.scenes.join("stanford-dragon/dragon.obj")),
        ("sponza", a.scenes.join("sponza-dabrovic/sponza.obj")),
        ("displaced-sphere", sphere),
    ];
    let mut rows = Vec::new();
    // Which processor and how busy: the same machine name has run on different
    // hosts, whose ratios differ.
    eprintln!("machine: {}", machine_line());
    if !a.json {
        print_header();
    }
    for (name, path) in &files {
        let wanted = |inside: bool| {
            let case = if inside { format!("{name}-inside") } else { name.to_string() };
            a.cases.is_empty() || a.cases.contains(&case)
        };
        if !wanted(false) && !wanted(true) {
            continue;
        }
        if !path.is_file() {
            eprintln!("skipping {name}: {} not found (docs/experiments.md says where to download it; --scenes DIR)", path.display());
            continue;
        }
        let mesh = BenchMesh::from_obj(path)?;
        for inside in [false, true] {
            if !wanted(inside) {
                continue;
            }
            for &t in &a.threads {
                // Back to back, so both engines see the same machine load.
                let mut emb = run_harness(&harness, path, inside, t, a.rays)?;
                // The comparison rows carry no traversal counts: no counting pass.
                let compare_opts = TraceOpts { counts: false, ..TraceOpts::all(a.stream) };
                let mut ours = run_mesh(&mesh, &a.accel, a.rays, inside, t, 1, &compare_opts)?;
                let mut paired = vec![pair_rows(&emb, &ours)];
                for _ in 1..a.repeats {
                    let (e, o) =
                        (run_harness(&harness, path, inside, t, a.rays)?, run_mesh(&mesh, &a.accel, a.rays, inside, t, 1, &compare_opts)?);
                    paired.push(pair_rows(&e, &o));
                    keep_best_embree(&mut emb, e);
                    keep_best_ours(&mut ours, o);
                }
                let mut new = pair_rows(&emb, &ours);
                add_paired(&mut new, &paired);
                for r in &new {
                    if a.json {
                        outln!("{}", serde_json::to_string(r)?);
                    } else {
                        print_row(r);
                    }
                }
                rows.extend(new);
            }
        }
    }
    if rows.is_empty() {
        bail!("no case could be run (models missing? see the messages above)");
    }
    eprintln!("machine at the end: {}", machine_line());
    Ok(())
}

/// The processor model, the logical CPU count and the load average, for the record
/// of a comparison (`unknown` where /proc does not say).
fn machine_line() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| cpu_model(&s)).unwrap_or_else(|| "unknown CPU".into());
    let n = std::thread::available_parallelism().map_or(0, |n| n.get());
    let load = std::fs::read_to_string("/proc/loadavg").ok().map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "));
    format!("{cpu}, {n} logical CPUs, load average {}", load.as_deref().unwrap_or("unknown"))
}

/// The `model name` of /proc/cpuinfo text (with family/model numbers, which name a
/// processor generation where the model name is generic, as under some hypervisors).
fn cpu_model(cpuinfo: &str) -> Option<String> {
    let field = |key: &str| {
        cpuinfo.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            (k.trim() == key).then(|| v.trim().to_string())
        })
    };
    let name = field("model name")?;
    Some(match (field("cpu family"), field("model")) {
        (Some(f), Some(m)) => format!("{name} (family {f} model {m})"),
        _ => name,
    })
}

/// Fills each row's median and range of the per-repeat ratios (rows of every
/// repeat in the same order, as `pair_rows` makes them).
fn add_paired(rows: &mut [CompareRow], repeats: &[Vec<CompareRow>]) {
    for (i, r) in rows.iter_mut().enumerate() {
        let mut v: Vec<f64> = repeats.iter().filter_map(|p| p.get(i)).map(|p| p.ratio).collect();
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            continue;
        }
        let n = v.len();
        r.paired_median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        r.paired_range = [v[0], v[n - 1]];
    }
}

/// Keeps, row by row, the faster of two harness runs.
fn keep_best_embree(best: &mut [serde_json::Value], new: Vec<serde_json::Value>) {
    for (b, n) in best.iter_mut().zip(new) {
        if n["mrays_per_s"].as_f64() > b["mrays_per_s"].as_f64() {
            *b = n;
        }
    }
}

/// Keeps, row by row, the faster of two photonlab runs.
fn keep_best_ours(best: &mut [BenchRow], new: Vec<BenchRow>) {
    for (b, n) in best.iter_mut().zip(new) {
        if n.mrays_per_s > b.mrays_per_s {
            *b = n;
        }
    }
}

/// Matches our rows with the harness's: one ray at a time with its one-ray rows, our
/// streams with its 8-ray packets (`intersect8`, diffuse rays only; camera streams
/// have no counterpart).
fn pair_rows(emb: &[serde_json::Value], ours: &[BenchRow]) -> Vec<CompareRow> {
    let mut out = Vec::new();
    for r in ours {
        let stream = r.api.starts_with("stream");
        let api = if stream {
            "intersect8"
        } else if r.rays == "shadow" {
            "occluded1"
        } else {
            "intersect1"
        };
        let Some(e) = emb.iter().find(|e| e["rays"] == r.rays.as_str() && e["api"] == api) else { continue };
        let f = |k: &str| e[k].as_f64().unwrap_or(f64::NAN);
        let ratio = r.mrays_per_s / f("mrays_per_s");
        out.push(CompareRow {
            scene: r.scene.clone(),
            rays: r.rays.clone(),
            api: if stream { format!("{}/{api}", r.api) } else { api.to_string() },
            threads: r.threads,
            engine: r.engine.clone(),
            embree_mrays_per_s: f("mrays_per_s"),
            photonlab_mrays_per_s: r.mrays_per_s,
            ratio,
            paired_median: ratio,
            paired_range: [ratio; 2],
            embree_hit_fraction: f("hit_fraction"),
            photonlab_hit_fraction: r.hit_fraction,
            embree_build_s: f("build_s"),
            photonlab_build_s: r.build_s,
        });
    }
    out
}

fn print_header() {
    outln!(
        "| {:<23} | {:<7} | {:<18} | {:>3} | {:<15} | {:>13} | {:>16} | {:>6} | {:>17} | {:>9} | {:>9} |",
        "scene",
        "rays",
        "api",
        "thr",
        "engine",
        "Embree Mrays/s",
        "photonlab Mrays/s",
        "ratio",
        "paired (range)",
        "hit (E)",
        "hit (p)"
    );
    outln!("|---|---|---|---:|---|---:|---:|---:|---:|---:|---:|");
}

fn print_row(r: &CompareRow) {
    outln!(
        "| {:<23} | {:<7} | {:<18} | {:>3} | {:<15} | {:>13.2} | {:>16.2} | {:>6.2} | {:>17} | {:>9.4} | {:>9.4} |",
        r.scene,
        r.rays,
        r.api,
        r.threads,
        r.engine,
        r.embree_mrays_per_s,
        r.photonlab_mrays_per_s,
        r.ratio,
        format!("{:.2} ({:.2}–{:.2})", r.paired_median, r.paired_range[0], r.paired_range[1]),
        r.embree_hit_fraction,
        r.photonlab_hit_fraction
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_harness_says_how_to_get_it() {
        let work = tempfile::tempdir().unwrap();
        let mut a = EmbreeArgs {
            harness: None,
            harness_dir: Some(work.path().join("nowhere")),
            scenes: work.path().into(),
            work_dir: work.path().join("build"),
            rays: 10,
            threads: vec![1],
            accel: vec!["bvh8".into()],
            cases: vec![],
            repeats: 1,
            json: false,
            stream: 0,
        };
        let e = locate_harness(&a).unwrap_err().to_string();
        assert!(e.contains("nowhere") && e.contains("--harness-dir") && e.contains("not part of the repository"), "{e}");
        // A folder without the sources names the file it looked for.
        a.harness_dir = Some(work.path().into());
        let e = locate_harness(&a).unwrap_err().to_string();
        assert!(e.contains("embree_bench.c") && e.contains("--harness-dir"), "{e}");
        // A binary built in the work folder earlier is found without a folder.
        std::fs::create_dir_all(&a.work_dir).unwrap();
        std::fs::write(a.work_dir.join("embree_bench"), b"").unwrap();
        a.harness_dir = None;
        assert_eq!(locate_harness(&a).unwrap(), a.work_dir.join("embree_bench"));
    }

    #[test]
    fn rows_pair_by_ray_set_and_api() {
        let emb: Vec<serde_json::Value> = [
            r#"{"engine":"embree","rays":"camera","api":"intersect1","mrays_per_s":10.0,"hit_fraction":0.5,"build_s":0.1}"#,
            r#"{"engine":"embree","rays":"diffuse","api":"intersect8","mrays_per_s":99.0,"hit_fraction":0.2,"build_s":0.1}"#,
            r#"{"engine":"embree","rays":"diffuse","api":"intersect1","mrays_per_s":4.0,"hit_fraction":0.2,"build_s":0.1}"#,
        ]
        .iter()
        .map(|s| serde_json::from_str(s).unwrap())
        .collect();
        let row = |rays: &str, m: f64| BenchRow {
            engine: "photonlab-bvh8".into(),
            scene: "x".into(),
            triangles: 1,
            rays: rays.into(),
            api: if rays == "shadow" { "occluded1" } else { "intersect1" }.into(),
            threads: 1,
            build_s: 0.1,
            mrays_per_s: m,
            cpu_mrays_per_s: m,
            hit_fraction: 0.2,
            n_rays: 10,
            node_tests_per_ray: Some(1.0),
            tri_tests_per_ray: Some(1.0),
            memory_bytes: 0,
            sah: None,
            simd: None,
        };
        let p = pair_rows(&emb, &[row("camera", 5.0), row("diffuse", 6.0), row("shadow", 1.0)]);
        assert_eq!(p.len(), 2, "shadow has no Embree row here");
        assert_eq!((p[0].rays.as_str(), p[0].ratio), ("camera", 0.5));
        assert_eq!((p[1].rays.as_str(), p[1].ratio), ("diffuse", 1.5), "intersect8 must not be paired with one ray at a time");
        // A stream is paired with the packets, and only for the diffuse rays.
        let stream = |rays: &str, m: f64| BenchRow { api: "stream8".into(), ..row(rays, m) };
        let p = pair_rows(&emb, &[stream("camera", 5.0), stream("diffuse", 198.0)]);
        assert_eq!(p.len(), 1, "camera streams have no Embree row");
        assert_eq!((p[0].rays.as_str(), p[0].api.as_str(), p[0].ratio), ("diffuse", "stream8/intersect8", 2.0));
    }

    #[test]
    fn paired_ratios_take_the_median_per_row() {
        let row = |rays: &str, ratio: f64| CompareRow {
            scene: "x".into(),
            rays: rays.into(),
            api: "intersect1".into(),
            threads: 1,
            engine: "photonlab-bvh8".into(),
            embree_mrays_per_s: 1.0,
            photonlab_mrays_per_s: ratio,
            ratio,
            paired_median: ratio,
            paired_range: [ratio; 2],
            embree_hit_fraction: 0.0,
            photonlab_hit_fraction: 0.0,
            embree_build_s: 0.0,
            photonlab_build_s: 0.0,
        };
        let reps: Vec<Vec<CompareRow>> =
            [[0.9, 2.0], [1.3, 1.0], [1.1, 3.0], [1.2, 4.0]].iter().map(|r| vec![row("camera", r[0]), row("diffuse", r[1])]).collect();
        let mut rows = vec![row("camera", 1.0), row("diffuse", 1.0)];
        add_paired(&mut rows, &reps);
        assert_eq!((rows[0].paired_median, rows[0].paired_range), (1.15, [0.9, 1.3]));
        assert_eq!((rows[1].paired_median, rows[1].paired_range), (2.5, [1.0, 4.0]));
        add_paired(&mut rows, &reps[..3]);
        assert_eq!(rows[0].paired_median, 1.1);
    }

    #[test]
    fn cpu_model_names_the_processor_generation() {
        let text = "processor\t: 0\nvendor_id\t: GenuineIntel\ncpu family\t: 6\nmodel\t\t: 207\nmodel name\t: Intel(R) Xeon(R) Processor\n";
        assert_eq!(cpu_model(text).as_deref(), Some("Intel(R) Xeon(R) Processor (family 6 model 207)"));
        assert_eq!(cpu_model("model name\t: AMD EPYC\n").as_deref(), Some("AMD EPYC"));
        assert_eq!(cpu_model("processor\t: 0\n"), None);
    }

    #[test]
    fn missing_harness_is_a_clear_error() {
        let dir = std::env::temp_dir().join(format!("photonlab-no-harness-{}", std::process::id()));
        let a = EmbreeArgs {
            harness: None,
            harness_dir: Some(dir.join("nowhere")),
            scenes: dir.join("scenes"),
            work_dir: dir.join("work"),
            rays: 10,
            threads: vec![1],
            accel: vec!["bvh8".into()],
            cases: vec![],
            repeats: 1,
            json: false,
            stream: 0,
        };
        let e = run(&a).unwrap_err().to_string();
        assert!(e.contains("nowhere") && e.contains("--harness-dir"), "{e}");
    }
}
