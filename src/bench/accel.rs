//! `bench accel`: acceleration-structure build time and single-ray throughput on the
//! ray sets of the Embree reference harness (`shared/bench/embree`, README "What is
//! measured"), so that figures from both compare on the same rays.
//!
//! The ray sets replicate `embree_bench.c` step by step, including its splitmix64
//! generator, seed and draw order: camera rays (1024² jittered pinhole, scanline
//! order, further passes re-jittered), diffuse bounce rays at camera hits (cosine
//! about the geometric normal flipped towards the viewer, origin offset 1e-4·diagonal)
//! and shadow rays from the same origins to a point light (only where the light is
//! on the outer side). They are generated once, before any timing, by tracing the
//! camera rays with the first accelerator named; every accelerator is then timed on
//! the same rays.

use crate::accel::{Accel, TraversalStats};
use crate::geometry::Ray;
use crate::registry;
use anyhow::{Context, Result, bail};
use clap::Args;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags of `bench accel`.
#[derive(Args, Debug, Clone)]
pub struct AccelArgs {
    /// OBJ file (only `v` and `f` lines are read; polygons are fan-triangulated).
    #[arg(long, conflicts_with = "builtin")]
    pub obj: Option<PathBuf>,
    /// Built-in mesh instead of an OBJ (`displaced-sphere`, or any built-in scene).
    #[arg(long)]
    pub builtin: Option<String>,
    /// Camera at the bounding-box centre (the harness's `--inside`).
    #[arg(long)]
    pub inside: bool,
    /// Rays per set.
    #[arg(long, default_value_t = 2_000_000)]
    pub rays: usize,
    /// Tracing (and build) threads; each traces a contiguous range.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Accelerators to time, comma-separated (the first also generates the rays);
    /// default: `render`'s default accelerator.
    #[arg(long, value_delimiter = ',', default_value = "bvh8")]
    pub accel: Vec<String>,
    /// Builds per accelerator; the best time is reported.
    #[arg(long, default_value_t = 1)]
    pub builds: usize,
    /// Scene name in the output (default: file stem, plus `-inside`).
    #[arg(long)]
    pub name: Option<String>,
    /// Print JSON lines (the harness's fields plus traversal counts) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also trace the camera and diffuse rays as streams with this many rays in flight
    /// per thread (`api` = `stream<K>`; the wide BVHs interleave 2, 4 or 8 rays'
    /// traversals, other values and accelerators trace one ray at a time).
    #[arg(long, default_value_t = 0)]
    pub stream: usize,
    /// Ray sets to trace, comma-separated (`camera`, `diffuse`, `shadow`; `''`: none,
    /// only the build and the ray generation); all three are always generated. One
    /// set alone, minus none, is what an instruction count per ray
    /// (`tools/ray_instructions.py`, under `valgrind --tool=cachegrind`) needs.
    #[arg(long, value_delimiter = ',', default_value = "camera,diffuse,shadow")]
    pub sets: Vec<String>,
    /// Skip the untimed second pass over each set that counts box and triangle tests
    /// (`nodes/r` and `tris/r` then read `-`, `null` in JSON): the timed pass never
    /// counts them, as renders do not, and an instruction count of the timed queries
    /// alone needs this.
    #[arg(long)]
    pub no_counts: bool,
}

/// The ray sets of the benchmark, in the order they are traced.
pub const SETS: [&str; 3] = ["camera", "diffuse", "shadow"];

/// What [`run_mesh`] traces besides the single-ray queries.
#[derive(Clone, Debug)]
pub struct TraceOpts {
    /// Also trace the camera and diffuse sets as streams with this many rays in
    /// flight (rows with `api` = `stream<K>`), when above 1.
    pub stream: usize,
    /// The sets traced (names of [`SETS`]).
    pub sets: Vec<String>,
    /// Whether a second, untimed pass counts box and triangle tests per ray.
    pub counts: bool,
}

/// The names of all ray sets, as `--sets` takes them.
pub fn all_sets() -> Vec<String> {
    SETS.iter().map(|s| s.to_string()).collect()
}

impl TraceOpts {
    /// Every set, with streams of `stream` rays.
    pub fn all(stream: usize) -> Self {
        TraceOpts { stream, sets: all_sets(), counts: true }
    }
}

/// A triangle soup with the vertex list the camera is framed on.
#[derive(Clone, Debug)]
pub struct BenchMesh {
    /// Scene name used in the output.
    pub name: String,
    /// Every `v` record (unused ones included, as the harness frames on all of them).
    pub vertices: Vec<Vec3>,
    /// Triangles after fan triangulation (degenerate ones kept, as the harness does).
    pub tris: Vec<[Vec3; 3]>,
}

/// Parses the geometry of an OBJ text like the harness: `v x y z` and `f` lines with
/// `a`, `a/b`, `a/b/c`, `a//c` or negative (relative) indices, polygons
/// fan-triangulated, faces with fewer than three vertices skipped, everything else
/// ignored. `path` only names the file in errors.
pub fn parse_obj_geometry(text: &str, path: &Path) -> Result<(Vec<Vec3>, Vec<[Vec3; 3]>)> {
    let mut verts: Vec<Vec3> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut poly: Vec<u32> = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let line = line.trim_start();
        let mut it = line.split_ascii_whitespace();
        match it.next() {
            Some("v") => {
                let mut xyz = [0.0f32; 3];
                for c in &mut xyz {
                    let tok = it.next().with_context(|| format!("{}:{}: vertex needs three coordinates", path.display(), ln + 1))?;
                    *c = tok.parse().with_context(|| format!("{}:{}: bad vertex coordinate `{tok}`", path.display(), ln + 1))?;
                    // Rust parses "nan" and "inf"; a non-finite vertex would poison the BVH bounds.
                    if !c.is_finite() {
                        bail!("{}:{}: vertex coordinate `{tok}` is not finite", path.display(), ln + 1);
                    }
                }
                verts.push(Vec3::from_array(xyz));
            }
            Some("f") => {
                poly.clear();
                for tok in it {
                    if tok.starts_with('#') {
                        break;
                    }
                    let idx_s = tok.split('/').next().unwrap_or("");
                    let idx: i64 = idx_s
                        .parse()
                        .ok()
                        .filter(|&i| i != 0)
                        .with_context(|| format!("{}:{}: bad face index `{tok}`", path.display(), ln + 1))?;
                    let n = verts.len() as i64;
                    let res = if idx > 0 { idx - 1 } else { n + idx };
                    if res < 0 || res >= n {
                        bail!("{}:{}: face index {idx} out of range ({n} vertices so far)", path.display(), ln + 1);
                    }
                    poly.push(res as u32);
                }
                for k in 1..poly.len().saturating_sub(1) {
                    faces.push([poly[0], poly[k], poly[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if faces.is_empty() {
        bail!("{}: the mesh has no triangles", path.display());
    }
    let tris = faces.iter().map(|f| [verts[f[0] as usize], verts[f[1] as usize], verts[f[2] as usize]]).collect();
    Ok((verts, tris))
}

impl BenchMesh {
    /// Loads an OBJ's geometry; the name is the file stem.
    pub fn from_obj(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let (vertices, tris) = parse_obj_geometry(&text, path)?;
        let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "mesh".into());
        Ok(BenchMesh { name, vertices, tris })
    }

    /// The triangles of a built-in scene (its vertices are the triangle corners).
    pub fn from_builtin(name: &str) -> Result<Self> {
        let s = crate::scene::builtin::builtin(name)?;
        let vertices = s.triangles.iter().flatten().copied().collect();
        Ok(BenchMesh { name: s.name, vertices, tris: s.triangles })
    }

    /// Writes the mesh as an indexed OBJ (`v`/`f` only; shared corners merged by bit
    /// pattern). Coordinates are printed in Rust's shortest round-trip form, so the
    /// harness reads exactly the same floats.
    pub fn write_obj(&self, path: &Path) -> Result<()> {
        use std::collections::HashMap;
        use std::io::Write;
        let mut index: HashMap<[u32; 3], u32> = HashMap::with_capacity(self.tris.len());
        let mut out = std::io::BufWriter::new(std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?);
        let mut faces = Vec::with_capacity(self.tris.len());
        writeln!(out, "# {}: {} triangles, written by photonlab bench", self.name, self.tris.len())?;
        for t in &self.tris {
            let mut f = [0u32; 3];
            for (k, p) in t.iter().enumerate() {
                let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
                let next = index.len() as u32;
                f[k] = *index.entry(key).or_insert_with(|| {
                    let _ = writeln!(out, "v {} {} {}", p.x, p.y, p.z);
                    next
                });
            }
            faces.push(f);
        }
        for f in faces {
            writeln!(out, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1)?;
        }
        out.flush().with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }
}

/// splitmix64 with the harness's seed (so the ray sets match its draw for draw).
struct SplitMix(u64);

impl SplitMix {
    fn new() -> Self {
        SplitMix(0x9E37_79B9_7F4A_7C15u64 ^ 20_240_601)
    }
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / 16_777_216.0)
    }
}

/// A benchmark ray: origin, unit direction and the far end of the valid interval.
#[derive(Clone, Copy, Debug)]
pub struct BenchRay {
    /// Origin.
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
    /// Valid for 0 < t < tfar.
    pub tfar: f32,
}

struct PinholeCamera {
    eye: Vec3,
    fwd: Vec3,
    right: Vec3,
    up: Vec3,
    cx: f32,
    cy: f32,
    span: f32,
    res: u64,
}

impl PinholeCamera {
    fn ray(&self, i: u64, rng: &mut SplitMix) -> BenchRay {
        let pix = i % (self.res * self.res);
        let px = (pix % self.res) as f32 + rng.next_f32();
        let py = (pix / self.res) as f32 + rng.next_f32();
        let sx = self.cx + (px / self.res as f32 - 0.5) * self.span;
        let sy = self.cy - (py / self.res as f32 - 0.5) * self.span;
        let d = (self.fwd + (self.right * sx + self.up * sy)).normalize();
        BenchRay { o: self.eye, d, tfar: f32::INFINITY }
    }
}

/// Cosine-distributed direction about the unit normal `n` (Duff et al. 2017 basis),
/// drawing two numbers as the harness does.
fn cosine_dir(n: Vec3, rng: &mut SplitMix) -> Vec3 {
    let r1 = rng.next_f32();
    let r2 = rng.next_f32();
    let phi = std::f32::consts::TAU * r1; // the harness's 6.2831853f rounds to TAU
    let s = r2.sqrt();
    let (lx, ly, lz) = (s * phi.cos(), s * phi.sin(), (1.0 - r2).max(0.0).sqrt());
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (t * lx + bt * ly + n * lz).normalize()
}

/// The three ray sets of one scene and camera placement.
#[derive(Clone, Debug)]
pub struct RaySets {
    /// Camera rays (`n` of them).
    pub camera: Vec<BenchRay>,
    /// Diffuse bounce rays (up to `n`).
    pub diffuse: Vec<BenchRay>,
    /// Shadow rays to the point light (up to `n`).
    pub shadow: Vec<BenchRay>,
    /// Camera rays traced to collect them.
    pub camera_traced: u64,
}

/// Generates the harness's ray sets, tracing camera rays with `accel` (single-threaded,
/// because the draw order depends on which camera rays hit).
pub fn generate_rays(mesh: &BenchMesh, accel: &dyn Accel, nrays: usize, inside: bool) -> Result<RaySets> {
    if nrays == 0 {
        bail!("--rays must be at least 1");
    }
    if mesh.vertices.is_empty() {
        bail!("{}: no vertices", mesh.name);
    }
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for v in &mesh.vertices {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    let ext = hi - lo;
    let centre = (lo + hi) * 0.5;
    let diag = ext.length();
    if !(diag.is_finite() && diag > 0.0) {
        bail!("{}: the bounding box is degenerate or not finite", mesh.name);
    }
    let mut res = 1024u64;
    while res > 1 && (res * res) as usize > nrays {
        res -= 1;
    }
    let world_up = Vec3::Y;
    let (cam, light) = if !inside {
        let eye = centre + Vec3::new(0.0, 0.2, 1.0) * diag;
        let fwd = (centre - eye).normalize();
        let right = fwd.cross(world_up).normalize();
        let up = right.cross(fwd);
        // Frame the projected vertices tightly (off-axis window, square pixels).
        let (mut xmin, mut xmax, mut ymin, mut ymax) = (f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY);
        for v in &mesh.vertices {
            let p = *v - eye;
            let z = p.dot(fwd);
            if z <= 0.0 {
                continue;
            }
            let (x, y) = (p.dot(right) / z, p.dot(up) / z);
            xmin = xmin.min(x);
            xmax = xmax.max(x);
            ymin = ymin.min(y);
            ymax = ymax.max(y);
        }
        let cam = PinholeCamera {
            eye,
            fwd,
            right,
            up,
            cx: 0.5 * (xmin + xmax),
            cy: 0.5 * (ymin + ymax),
            span: 1.02 * (xmax - xmin).max(ymax - ymin),
            res,
        };
        (cam, Vec3::new(centre.x + 0.1 * diag, hi.y + 0.5 * diag, centre.z + 0.2 * diag))
    } else {
        let fwd = if ext.x >= ext.z { Vec3::X } else { Vec3::Z };
        let right = fwd.cross(world_up).normalize();
        let up = right.cross(fwd);
        let span = 2.0 * (35.0f32 * std::f32::consts::PI / 180.0).tan();
        (PinholeCamera { eye: centre, fwd, right, up, cx: 0.0, cy: 0.0, span, res }, centre + Vec3::new(0.0, 0.25 * ext.y, 0.0))
    };

    let mut rng = SplitMix::new();
    let camera: Vec<BenchRay> = (0..nrays as u64).map(|i| cam.ray(i, &mut rng)).collect();
    let eps = 1e-4 * diag;
    let (mut diffuse, mut shadow) = (Vec::with_capacity(nrays), Vec::with_capacity(nrays));
    let kmax = 64 * nrays as u64;
    let mut stats = TraversalStats::default();
    let mut k = 0u64;
    while k < kmax && (diffuse.len() < nrays || shadow.len() < nrays) {
        let cr = if (k as usize) < nrays { camera[k as usize] } else { cam.ray(k, &mut rng) };
        k += 1;
        let Some(hit) = accel.intersect(&Ray::new(cr.o, cr.d), cr.tfar, &mut stats) else { continue };
        let p = cr.o + cr.d * hit.t;
        let t = &mesh.tris[hit.tri as usize];
        let ng = (t[1] - t[0]).cross(t[2] - t[0]);
        let nl = ng.length();
        if nl.is_nan() || nl <= 0.0 {
            continue;
        }
        let mut n = ng / nl;
        if n.dot(cr.d) > 0.0 {
            n = -n;
        }
        let o = p + n * eps;
        if diffuse.len() < nrays {
            let w = cosine_dir(n, &mut rng);
            diffuse.push(BenchRay { o, d: w, tfar: f32::INFINITY });
        }
        let tl = light - o;
        let dist = tl.length();
        if shadow.len() < nrays && tl.dot(n) > 0.0 && dist > 0.0 {
            shadow.push(BenchRay { o, d: tl / dist, tfar: dist });
        }
    }
    Ok(RaySets { camera, diffuse, shadow, camera_traced: k })
}

/// Which query a ray set is timed with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// Closest hit (`intersect1`).
    Closest,
    /// Any hit (`occluded1`).
    Any,
    /// Closest hits through [`Accel::intersect_stream`] with this many rays in flight
    /// (`stream<K>`).
    Stream(usize),
}

impl Query {
    /// The `api` field of a row (the harness's names for its own queries).
    fn api(self) -> String {
        match self {
            Query::Closest => "intersect1".into(),
            Query::Any => "occluded1".into(),
            Query::Stream(k) => format!("stream{k}"),
        }
    }
}

/// CPU time consumed by the calling thread, seconds (None where unsupported).
fn thread_cpu_secs() -> Option<f64> {
    #[cfg(target_os = "linux")]
    {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: clock_gettime writes only into `ts`.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        if rc == 0 {
            return Some(ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64);
        }
    }
    None
}

/// The outcome of tracing one ray set.
#[derive(Clone, Copy, Debug, Default)]
pub struct TraceResult {
    /// Wall time from the first thread's start to the last join.
    pub secs: f64,
    /// CPU time of the tracing threads, summed (wall time × threads where unknown).
    /// On a shared machine this excludes time spent descheduled.
    pub cpu_secs: f64,
    /// Rays that hit (closest) or were occluded (any).
    pub hits: u64,
    /// Traversal counters summed over the threads.
    pub stats: TraversalStats,
}

/// Traces `rays` over `threads` threads, each a contiguous range (one ray at a time, or
/// as a stream with `Query::Stream`), counting box and triangle tests if `count`
/// (which costs time: [`TraversalStats::count_work`]).
pub fn trace(accel: &dyn Accel, rays: &[BenchRay], query: Query, threads: usize, count: bool) -> TraceResult {
    let threads = threads.max(1);
    let chunk = rays.len().div_ceil(threads).max(1);
    let t0 = Instant::now();
    let parts: Vec<(u64, TraversalStats, Option<f64>)> = std::thread::scope(|s| {
        let handles: Vec<_> = rays
            .chunks(chunk)
            .map(|part| {
                s.spawn(move || {
                    let c0 = thread_cpu_secs();
                    let mut st = TraversalStats { count_work: count, ..Default::default() };
                    let mut hits = 0u64;
                    match query {
                        Query::Closest => {
                            for r in part {
                                hits += accel.intersect(&Ray::new(r.o, r.d), r.tfar, &mut st).is_some() as u64;
                            }
                        }
                        Query::Stream(k) => {
                            // In runs of 1024 rays, as a renderer's batch would hand them over.
                            let mut buf = Vec::with_capacity(1024);
                            let mut out = vec![None; 1024];
                            for c in part.chunks(1024) {
                                buf.clear();
                                buf.extend(c.iter().map(|r| (Ray::new(r.o, r.d), r.tfar)));
                                accel.intersect_stream(&buf, &mut out[..c.len()], k, &mut st);
                                hits += out[..c.len()].iter().filter(|h| h.is_some()).count() as u64;
                            }
                        }
                        Query::Any => {
                            for r in part {
                                hits += accel.occluded(&Ray::new(r.o, r.d), r.tfar, &mut st) as u64;
                            }
                        }
                    }
                    let cpu = c0.zip(thread_cpu_secs()).map(|(a, b)| b - a);
                    (hits, st, cpu)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("tracing thread panicked")).collect()
    });
    let secs = t0.elapsed().as_secs_f64();
    let mut out = TraceResult { secs, ..Default::default() };
    for (h, st, cpu) in parts {
        out.hits += h;
        out.stats.add(&st);
        out.cpu_secs += cpu.unwrap_or(secs);
    }
    out
}

/// One output row (the harness's JSON fields plus traversal counts per ray).
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchRow {
    /// `photonlab-<accel>`.
    pub engine: String,
    /// Scene name.
    pub scene: String,
    /// Triangle count.
    pub triangles: usize,
    /// `camera`, `diffuse` or `shadow`.
    pub rays: String,
    /// `intersect1` or `occluded1`.
    pub api: String,
    /// Tracing threads.
    pub threads: usize,
    /// Best build time, seconds.
    pub build_s: f64,
    /// Millions of rays per second, total over the threads.
    pub mrays_per_s: f64,
    /// Millions of rays per second of tracing-thread CPU time (per core; not
    /// disturbed by time spent descheduled on a shared machine).
    pub cpu_mrays_per_s: f64,
    /// Hit fraction (shadow: occluded fraction).
    pub hit_fraction: f64,
    /// Rays in the set.
    pub n_rays: usize,
    /// Ray/box tests per ray (from the untimed counting pass; `None` without it).
    pub node_tests_per_ray: Option<f64>,
    /// Ray/triangle tests per ray (as `node_tests_per_ray`).
    pub tri_tests_per_ray: Option<f64>,
    /// Bytes of the structure (nodes + triangle data).
    pub memory_bytes: usize,
    /// SAH cost as Embree's `verbose=3` statistics print it (wide BVHs only).
    pub sah: Option<f64>,
    /// Traversal instruction-set level (wide BVHs only; `PHOTONLAB_SIMD` can lower it).
    pub simd: Option<&'static str>,
}

/// Builds `name` over the mesh `builds` times with `threads` build threads; returns
/// the last structure and the best time.
pub fn build_accel(name: &str, tris: &[[Vec3; 3]], threads: usize, builds: usize) -> Result<(Box<dyn Accel>, f64)> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build().context("creating the build thread pool")?;
    let mut best = f64::INFINITY;
    let mut out: Option<Box<dyn Accel>> = None;
    for _ in 0..builds.max(1) {
        drop(out.take()); // free the previous structure before the next build
        let t0 = Instant::now();
        let a = pool.install(|| registry::make_accel(name, tris))?;
        best = best.min(t0.elapsed().as_secs_f64());
        out = Some(a);
    }
    Ok((out.expect("at least one build"), best))
}

/// Runs the whole benchmark for one mesh and camera placement: builds every
/// accelerator, generates the rays with the first, times each set with each.
/// `opts` picks the sets traced and the stream width.
pub fn run_mesh(
    mesh: &BenchMesh,
    accels: &[String],
    nrays: usize,
    inside: bool,
    threads: usize,
    builds: usize,
    opts: &TraceOpts,
) -> Result<Vec<BenchRow>> {
    if accels.is_empty() {
        bail!("--accel: name at least one accelerator");
    }
    if let Some(bad) = opts.sets.iter().find(|s| !s.is_empty() && !SETS.contains(&s.as_str())) {
        bail!("--sets: unknown ray set `{bad}` (known: {})", SETS.join(", "));
    }
    let stream = opts.stream;
    for a in accels {
        registry::check_accel(a)?;
    }
    let scene = if inside && !mesh.name.ends_with("-inside") { format!("{}-inside", mesh.name) } else { mesh.name.clone() };
    let mut built = Vec::new();
    for a in accels {
        let (acc, build_s) = build_accel(a, &mesh.tris, threads, builds)?;
        built.push((a.clone(), acc, build_s));
    }
    let t0 = Instant::now();
    let sets = generate_rays(mesh, built[0].1.as_ref(), nrays, inside)?;
    eprintln!(
        "{scene}: {} triangles; {} camera, {} diffuse, {} shadow rays from {} camera rays in {:.2} s",
        mesh.tris.len(),
        sets.camera.len(),
        sets.diffuse.len(),
        sets.shadow.len(),
        sets.camera_traced,
        t0.elapsed().as_secs_f64()
    );
    let mut rows = Vec::new();
    let mut cases =
        vec![("camera", &sets.camera, Query::Closest), ("diffuse", &sets.diffuse, Query::Closest), ("shadow", &sets.shadow, Query::Any)];
    if stream > 1 {
        cases.insert(2, ("diffuse", &sets.diffuse, Query::Stream(stream)));
        cases.insert(1, ("camera", &sets.camera, Query::Stream(stream)));
    }
    cases.retain(|c| opts.sets.iter().any(|s| s == c.0));
    for (set, rays, query) in cases {
        if rays.is_empty() {
            continue;
        }
        for (name, acc, build_s) in &built {
            let r = trace(acc.as_ref(), rays, query, threads, false);
            let n = rays.len() as f64;
            let counted = opts.counts.then(|| trace(acc.as_ref(), rays, query, threads, true).stats);
            rows.push(BenchRow {
                engine: format!("photonlab-{name}"),
                scene: scene.clone(),
                triangles: mesh.tris.len(),
                rays: set.into(),
                api: query.api(),
                threads,
                build_s: *build_s,
                mrays_per_s: n / r.secs.max(1e-12) * 1e-6,
                cpu_mrays_per_s: n / r.cpu_secs.max(1e-12) * 1e-6,
                hit_fraction: r.hits as f64 / n,
                n_rays: rays.len(),
                node_tests_per_ray: counted.map(|c| c.node_tests as f64 / n),
                tri_tests_per_ray: counted.map(|c| c.tri_tests as f64 / n),
                memory_bytes: acc.memory_bytes(),
                sah: acc.sah_cost(),
                simd: acc.simd_level(),
            });
        }
    }
    Ok(rows)
}

/// Prints rows as an aligned table.
pub fn print_table(rows: &[BenchRow]) {
    outln!(
        "{:<24} {:<18} {:<8} {:<10} {:>3} {:>9} {:>9} {:>8} {:>9} {:>8} {:>8} {:>8} {:>7}",
        "scene",
        "engine",
        "rays",
        "api",
        "thr",
        "Mrays/s",
        "cpu Mr/s",
        "hit",
        "n_rays",
        "nodes/r",
        "tris/r",
        "build_s",
        "MB"
    );
    for r in rows {
        outln!(
            "{:<24} {:<18} {:<8} {:<10} {:>3} {:>9.3} {:>9.3} {:>8.4} {:>9} {:>8} {:>8} {:>8.3} {:>7.1}",
            r.scene,
            r.engine,
            r.rays,
            r.api,
            r.threads,
            r.mrays_per_s,
            r.cpu_mrays_per_s,
            r.hit_fraction,
            r.n_rays,
            r.node_tests_per_ray.map_or("-".into(), |v| format!("{v:.1}")),
            r.tri_tests_per_ray.map_or("-".into(), |v| format!("{v:.2}")),
            r.build_s,
            r.memory_bytes as f64 / 1e6
        );
    }
}

/// Runs `bench accel`.
pub fn run(a: &AccelArgs) -> Result<()> {
    if a.threads == 0 || a.threads > 256 {
        bail!("--threads must be between 1 and 256, got {}", a.threads);
    }
    let mut mesh = match (&a.obj, &a.builtin) {
        (Some(p), _) => BenchMesh::from_obj(p)?,
        (None, Some(b)) => BenchMesh::from_builtin(b)?,
        (None, None) => bail!("bench accel: give --obj FILE.obj or --builtin displaced-sphere"),
    };
    if let Some(n) = &a.name {
        mesh.name = n.clone();
    }
    if a.stream > 64 {
        bail!("--stream: at most 64 rays in flight, got {}", a.stream);
    }
    let rows = run_mesh(
        &mesh,
        &a.accel,
        a.rays,
        a.inside,
        a.threads,
        a.builds,
        &TraceOpts { stream: a.stream, sets: a.sets.clone(), counts: !a.no_counts },
    )?;
    if a.json {
        for r in &rows {
            outln!("{}", serde_json::to_string(r)?);
        }
    } else {
        print_table(&rows);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_geometry_fans_and_negative_indices() {
        let text = "# c\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1/1/1 2//1 3 4\nf -4 -3 -2 # tail\nf 1 2\n";
        let (v, t) = parse_obj_geometry(text, Path::new("q.obj")).unwrap();
        assert_eq!(v.len(), 4);
        assert_eq!(t.len(), 3);
        assert_eq!(t[1], [v[0], v[2], v[3]]);
        assert_eq!(t[2], [v[0], v[1], v[2]]);
        let e = parse_obj_geometry("v 0 0 0\nf 1 2 3\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("bad.obj:2") && e.contains("out of range"), "{e}");
        assert!(parse_obj_geometry("v 0 0\n", Path::new("b.obj")).is_err());
        let e = parse_obj_geometry("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", Path::new("n.obj")).unwrap_err().to_string();
        assert!(e.contains("n.obj:2") && e.contains("not finite"), "{e}");
        assert!(parse_obj_geometry("v 0 0 0\n", Path::new("b.obj")).unwrap_err().to_string().contains("no triangles"));
        assert!(parse_obj_geometry("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 0 2\n", Path::new("b.obj")).is_err());
    }

    #[test]
    fn splitmix_matches_reference_values() {
        // First outputs of splitmix64 seeded as in embree_bench.c, computed by hand from
        // the published algorithm: a changed constant or shift breaks this.
        let mut r = SplitMix(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn ray_sets_follow_the_definition() {
        let mesh = BenchMesh::from_builtin("furnace").unwrap();
        let acc = registry::make_accel("bvh", &mesh.tris).unwrap();
        // Inside a closed sphere every camera ray hits, so the sets fill in one pass.
        let s = generate_rays(&mesh, acc.as_ref(), 1000, true).unwrap();
        assert_eq!((s.camera.len(), s.diffuse.len()), (1000, 1000));
        assert_eq!(s.camera_traced, 1000);
        for r in s.diffuse.iter().chain(&s.shadow).chain(&s.camera) {
            assert!((r.d.length() - 1.0).abs() < 1e-5);
        }
        // Inside a closed convex shell with the light inside it: every diffuse ray
        // leaves towards the interior and hits the shell again (a wrongly flipped
        // normal or offset would let rays escape), every origin sees the light.
        let mut st = TraversalStats::default();
        assert_eq!(trace(acc.as_ref(), &s.diffuse, Query::Closest, 2, false).hits, 1000);
        assert_eq!(s.shadow.len(), 1000);
        assert_eq!(trace(acc.as_ref(), &s.shadow, Query::Any, 1, false).hits, 0);
        // Streams: the same hits and traversal counts as one ray at a time.
        let w = registry::make_accel("bvh8", &mesh.tris).unwrap();
        let one = trace(w.as_ref(), &s.diffuse, Query::Closest, 1, true);
        assert!(one.stats.node_tests > 0 && one.stats.tri_tests > 0, "{:?}", one.stats);
        for k in [2, 4, 8] {
            let st = trace(w.as_ref(), &s.diffuse, Query::Stream(k), 2, true);
            assert_eq!((st.hits, st.stats), (one.hits, one.stats), "stream{k}");
            // Without counting, neither counts.
            let (a, b) =
                (trace(w.as_ref(), &s.diffuse, Query::Stream(k), 2, false), trace(w.as_ref(), &s.diffuse, Query::Closest, 1, false));
            assert_eq!((a.hits, a.stats.node_tests + a.stats.tri_tests), (one.hits, 0), "stream{k}");
            assert_eq!((b.hits, b.stats.node_tests + b.stats.tri_tests), (one.hits, 0));
        }
        for r in &s.shadow {
            assert!(r.tfar > 0.0 && r.tfar.is_finite() && !acc.occluded(&Ray::new(r.o, r.d), r.tfar, &mut st));
        }
        let again = generate_rays(&mesh, acc.as_ref(), 1000, true).unwrap();
        assert_eq!(again.diffuse[999].d, s.diffuse[999].d);
    }

    /// `--sets` traces only the sets named (in the usual order), and rejects others.
    #[test]
    fn only_the_chosen_ray_sets_are_traced() {
        let mesh = BenchMesh::from_builtin("furnace").unwrap();
        let sets = |names: &[&str], stream| TraceOpts { stream, sets: names.iter().map(|s| s.to_string()).collect(), counts: true };
        let run = |o: &TraceOpts| run_mesh(&mesh, &["bvh8".into()], 500, true, 1, 1, o);
        let rows = run(&sets(&["shadow", "camera"], 4)).unwrap();
        let got: Vec<(&str, &str)> = rows.iter().map(|r| (r.rays.as_str(), r.api.as_str())).collect();
        assert_eq!(got, [("camera", "intersect1"), ("camera", "stream4"), ("shadow", "occluded1")]);
        assert_eq!(run(&TraceOpts::all(0)).unwrap().len(), 3);
        assert!(run(&sets(&[""], 8)).unwrap().is_empty());
        let err = run(&sets(&["diffuse", "glossy"], 0)).unwrap_err().to_string();
        assert!(err.contains("`glossy`") && err.contains("camera, diffuse, shadow"), "{err}");
    }
}
