//! `photonlab bench photons`: how the photon integrator's time and memory grow with
//! the photon count (gather `precomputed`, built-in `cornell`, 64², 1 spp by default).
//!
//! Each count runs in a child process (the current executable re-invoked with the
//! hidden `--child` flag), so that the peak resident set (`VmHWM` of
//! `/proc/self/status`, read by the child after its render) belongs to that run
//! alone. Per count it reports the photon pass (tracing), the map build (kd-trees
//! and the global grid), the precomputation of irradiance, the render pass, the peak
//! resident set and that peak divided by the number of stored photons.

use crate::config::RenderConfig;
use crate::pipeline::render_scene;
use crate::scene::builtin::builtin;
use anyhow::{Context, Result, bail};
use clap::Args;

/// Flags of `bench photons`.
#[derive(Args, Debug, Clone)]
pub struct PhotonsArgs {
    /// Photons in the direct + indirect maps, one run per count (e.g. 1e6,4e6,1.6e7,1e8).
    #[arg(long, value_delimiter = ',', default_value = "1e6,4e6,1.6e7", value_parser = parse_count)]
    pub counts: Vec<u64>,
    /// Built-in scene.
    #[arg(long, default_value = "cornell")]
    pub scene: String,
    /// Gather plug-in of the photon integrator.
    #[arg(long, default_value = "precomputed")]
    pub gather: String,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 64)]
    pub size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Run one count in this process and print its row as JSON (used by the parent).
    #[arg(long, hide = true)]
    pub child: Option<u64>,
}

/// A count such as `1000000`, `1e6` or `1.6e7`.
fn parse_count(s: &str) -> Result<u64, String> {
    let v: f64 = s.trim().parse().map_err(|_| format!("`{s}` is not a photon count"))?;
    if !((1.0..=4e9).contains(&v) && v.fract() == 0.0) {
        return Err(format!("photon count `{s}` must be a whole number from 1 to 4e9"));
    }
    Ok(v as u64)
}

/// One result row (one JSON line).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Row {
    bench: String,
    scene: String,
    gather: String,
    photons: u64,
    /// Photons stored in all maps.
    stored: u64,
    threads: usize,
    /// Photon tracing (the photon pass without building the maps).
    trace_s: f64,
    /// kd-trees and the global grid.
    build_s: f64,
    /// Precomputed irradiance (0 for gathers without it).
    precompute_s: f64,
    /// Render pass.
    render_s: f64,
    /// Peak resident set of the run's process.
    peak_rss_bytes: u64,
    /// Peak resident set over stored photons.
    bytes_per_photon: f64,
    /// Bytes the photon maps and the global grid hold (the integrator's count).
    map_bytes: f64,
    precomputed_points: f64,
    load_average: Option<f64>,
}

/// Peak resident set of this process (`VmHWM`), in bytes.
pub fn peak_rss() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn config(args: &PhotonsArgs, photons: u64) -> Result<RenderConfig> {
    let photons = u32::try_from(photons).context("bench photons: counts above 4294967295 are not supported")?;
    Ok(RenderConfig {
        integrator: "photon".into(),
        spp: args.spp,
        threads: args.threads,
        resolution: Some([args.size, args.size]),
        ..RenderConfig::default()
    }
    .with("gather", args.gather.as_str())
    .with("photons", photons)
    .with("caustic_photons", 0)
    // Room for every path a large count needs (each stores about one photon or more).
    .with("max_emitted", (4 * photons as i64).max(20_000_000)))
}

/// One count in this process.
fn child(args: &PhotonsArgs, photons: u64) -> Result<Row> {
    let cfg = config(args, photons)?;
    let out = render_scene(builtin(&args.scene)?, &cfg, true)?;
    let x = |k: &str| out.extra.get(k).copied().unwrap_or(0.0);
    let trace = x("photon_trace_s");
    // `kdtree_build_s` = the maps' kd-trees (inside the photon pass) + the global
    // grid; `precompute_s` = the global grid + the precomputation.
    let tree_build = x("photon_pass_s") - trace;
    let grid = x("kdtree_build_s") - tree_build;
    let stored = (x("photons_direct") + x("photons_indirect") + x("photons_caustic")) as u64;
    let peak = peak_rss().unwrap_or(0);
    Ok(Row {
        bench: "photons".into(),
        scene: args.scene.clone(),
        gather: args.gather.clone(),
        photons,
        stored,
        threads: out.threads,
        trace_s: trace,
        build_s: x("kdtree_build_s"),
        precompute_s: (x("precompute_s") - grid).max(0.0),
        render_s: out.timings.render_s,
        peak_rss_bytes: peak,
        bytes_per_photon: peak as f64 / stored.max(1) as f64,
        map_bytes: x("photon_map_bytes"),
        precomputed_points: x("precomputed_points"),
        load_average: super::scaling::load_average(),
    })
}

/// Runs `bench photons` and returns its rows (also printed).
pub fn run(args: &PhotonsArgs) -> Result<Vec<Row>> {
    if args.size == 0 || args.spp == 0 {
        bail!("bench photons: --size and --spp must be at least 1");
    }
    if let Some(n) = args.child {
        let row = child(args, n)?;
        outln!("{}", serde_json::to_string(&row)?);
        return Ok(vec![row]);
    }
    if args.counts.is_empty() {
        bail!("bench photons: --counts is empty");
    }
    let exe = std::env::current_exe().context("bench photons: cannot find the running executable")?;
    let mut rows = Vec::new();
    for &n in &args.counts {
        config(args, n)?;
        let mut cmd = std::process::Command::new(&exe);
        cmd.args(["bench", "photons", "--child", &n.to_string()])
            .args(["--scene", &args.scene, "--gather", &args.gather])
            .args(["--size", &args.size.to_string(), "--spp", &args.spp.to_string(), "--threads", &args.threads.to_string()])
            .stderr(std::process::Stdio::inherit());
        let out = cmd.output().with_context(|| format!("bench photons: cannot run {}", exe.display()))?;
        if !out.status.success() {
            bail!("bench photons: the run with {n} photons failed ({})", out.status);
        }
        let text = String::from_utf8_lossy(&out.stdout);
        let line = text.lines().rev().find(|l| l.starts_with('{')).context("bench photons: a child printed no result")?;
        let row: Row = serde_json::from_str(line).context("bench photons: unreadable child result")?;
        if args.json {
            outln!("{}", serde_json::to_string(&row)?);
        }
        rows.push(row);
    }
    if !args.json {
        outln!(
            "bench photons: {} ({}), {}x{} px, {} spp, {} threads, one process per count",
            args.scene,
            args.gather,
            args.size,
            args.size,
            args.spp,
            rows.first().map_or(0, |r| r.threads)
        );
        outln!("| photons | stored | trace s | build s | precompute s | render s | peak RSS MB | B/photon | map B/photon | load |");
        outln!("|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            outln!(
                "| {:.3e} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.0} | {:.1} | {:.1} | {} |",
                r.photons as f64,
                r.stored,
                r.trace_s,
                r.build_s,
                r.precompute_s,
                r.render_s,
                r.peak_rss_bytes as f64 / 1e6,
                r.bytes_per_photon,
                r.map_bytes / r.stored.max(1) as f64,
                r.load_average.map_or("?".into(), |l| format!("{l:.1}"))
            );
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_parse() {
        assert_eq!(parse_count("1e6"), Ok(1_000_000));
        assert_eq!(parse_count("1.6e7"), Ok(16_000_000));
        assert_eq!(parse_count("250000"), Ok(250_000));
        assert!(parse_count("0").is_err() && parse_count("1.5").is_err() && parse_count("x").is_err() && parse_count("1e10").is_err());
    }

    #[test]
    fn peak_rss_is_read() {
        let v = std::hint::black_box(vec![1u8; 8 << 20]);
        assert!(peak_rss().unwrap() >= v.len() as u64);
    }
}
