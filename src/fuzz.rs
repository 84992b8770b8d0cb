//! `photonlab fuzz`: a mutation fuzzer for the input readers — scene TOML, OBJ, MTL,
//! experiment manifests, Mitsuba XML scenes, PLY and serialized meshes and texture
//! images (PNG, JPEG, EXR) — on stable Rust (no nightly, no sanitizer runtime).
//!
//! Seeds are real files (the built-in scenes exported through the scene contract,
//! the shipped manifests, and any `--corpus` directory); each input is a seed
//! mutated 1–8 times (bit flips, byte insertions and deletions, duplicated or
//! swapped ranges, lines spliced from other seeds, numbers replaced by hostile
//! values, truncation) or, one in ten, random bytes. Every input must end in `Ok` or
//! an error; a panic is caught, counted and saved under `--out`, and a watchdog
//! saves and reports any input that runs longer than `--timeout` seconds.

use crate::experiment::manifest::Manifest;
use crate::scene::obj::{parse_mtl, parse_obj};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Flags of `fuzz`.
#[derive(Args, Debug, Clone)]
pub struct FuzzArgs {
    /// Number of inputs.
    #[arg(long, default_value_t = 100_000)]
    pub inputs: u64,
    /// Seed of the mutations.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Extra seed files: every `.toml`, `.obj` and `.mtl` under these directories.
    #[arg(long)]
    pub corpus: Vec<PathBuf>,
    /// Where inputs that panic or hang are saved (and the scratch files live).
    #[arg(long, default_value = "results/fuzz")]
    pub out: PathBuf,
    /// Seconds one input may take before it counts as a hang.
    #[arg(long, default_value_t = 10)]
    pub timeout: u64,
}

/// Which reader an input goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    /// Scene TOML (`load_scene`, with the OBJ/MTL it names).
    Scene,
    /// OBJ (`parse_obj`).
    Obj,
    /// MTL (`parse_mtl`).
    Mtl,
    /// Experiment manifest (`Manifest::parse`).
    Manifest,
    /// Mitsuba XML scene (parse and build, with the files it names).
    Xml,
    /// PLY mesh (`parse_ply`).
    Ply,
    /// Mitsuba serialized mesh (`parse_serialized`): the input as a file (meshes 0
    /// and 1) and as the uncompressed body of a one-mesh file, so the mesh reader sees
    /// corrupt counts and flags, not only a corrupt zlib stream.
    Serialized,
    /// Texture image (PNG, JPEG or EXR by its magic bytes; `Image::decode`).
    Image,
}

/// A small XML seed using most of the supported elements.
const XML_SEED: &str = r#"<scene version="3.0.0">
<default name="r" value="0.5"/>
<sensor type="perspective"><float name="fov" value="40"/><string name="fov_axis" value="smaller"/>
<transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
<sampler type="independent"><integer name="sample_count" value="4"/></sampler>
<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/><rfilter type="box"/></film></sensor>
<bsdf type="twosided" id="w"><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"><transform name="to_uv"><scale value="4"/></transform></texture></bsdf></bsdf>
<shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/></transform><ref id="w"/></shape>
<shape type="cube"><transform name="to_world"><scale value="$r"/><matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/></transform><bsdf type="dielectric"><string name="int_ior" value="water"/></bsdf></shape>
<shape type="disk"><boolean name="flip_normals" value="true"/><emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter></shape>
<emitter type="spot"><float name="cutoff_angle" value="30"/></emitter>
<emitter type="point"><point name="position" x="0" y="1" z="0"/></emitter>
<emitter type="directional"><vector name="direction" value="0 -1 0"/></emitter>
<emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>
</scene>
"#;

/// A small ASCII PLY seed (a quad with normals and UVs).
const PLY_SEED: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n1 1 0 0 0 1 1 1\n0 1 0 0 0 1 0 1\n4 0 1 2 3\n";

fn exr_is_piz(input: &[u8]) -> bool {
    match exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(input), false) {
        Ok(m) => m.headers.iter().any(|h| h.compression == exr::compression::Compression::PIZ),
        Err(_) => false,
    }
}

fn image_kind(input: &[u8]) -> &'static str {
    if input.starts_with(b"\x89PNG") {
        "png"
    } else if input.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        "exr"
    } else {
        "jpg"
    }
}

/// Counts of one fuzzing run.
#[derive(Clone, Debug, Default)]
pub struct FuzzReport {
    /// Inputs run.
    pub inputs: u64,
    /// Inputs accepted (`Ok`).
    pub ok: u64,
    /// Inputs rejected with an error.
    pub errors: u64,
    /// Inputs that panicked (saved under `out`).
    pub panics: Vec<PathBuf>,
    /// Wall time.
    pub seconds: f64,
    /// The slowest input's time (seconds) and target; it is saved as `slowest.bin`.
    pub slowest: (f64, Option<Target>),
    /// The slowest input.
    pub slowest_input: Vec<u8>,
}

/// PCG-style 64-bit generator (splitmix64): deterministic mutations from the seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const HOSTILE: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "0",
    "-0",
    "-1",
    "1e39",
    "1e-45",
    "4294967296",
    "18446744073709551616",
    "-2147483649",
    "99999999",
    "\"\"",
    "[]",
    "{}",
    "0x10",
    "1_0",
    "+",
    "1e",
    "//",
    "\u{0}",
    "é",
];

fn mutate(seed: &[u8], others: &[&[u8]], rng: &mut Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(8) {
        let n = v.len();
        match rng.below(9) {
            0 if n > 0 => {
                let i = rng.below(n);
                v[i] ^= 1 << rng.below(8);
            }
            1 => {
                let i = rng.below(n + 1);
                let b = if rng.below(2) == 0 { rng.next() as u8 } else { b"\n =[]{}\"#./-0123456789fvn"[rng.below(25)] };
                v.insert(i, b);
            }
            2 if n > 0 => {
                let i = rng.below(n);
                let len = 1 + rng.below(16.min(n - i));
                v.drain(i..i + len);
            }
            3 if n > 0 => {
                let i = rng.below(n);
                let len = 1 + rng.below(64.min(n - i));
                let piece = v[i..i + len].to_vec();
                let at = rng.below(n + 1);
                v.splice(at..at, piece);
            }
            4 if !others.is_empty() => {
                // Splice a line of another seed in place of one of ours.
                let o = others[rng.below(others.len())];
                let lines: Vec<&[u8]> = o.split(|b| *b == b'\n').collect();
                let line = lines[rng.below(lines.len())];
                let ours: Vec<usize> =
                    std::iter::once(0).chain(v.iter().enumerate().filter(|(_, b)| **b == b'\n').map(|(i, _)| i + 1)).collect();
                let at = ours[rng.below(ours.len())];
                let mut piece = line.to_vec();
                piece.push(b'\n');
                v.splice(at..at, piece);
            }
            5 | 6 => {
                // Replace a number (a run of digits, '.', '-', 'e') by a hostile value.
                let starts: Vec<usize> =
                    (0..n).filter(|&i| v[i].is_ascii_digit() && (i == 0 || !v[i - 1].is_ascii_alphanumeric())).collect();
                if !starts.is_empty() {
                    let s = starts[rng.below(starts.len())];
                    let mut e = s;
                    while e < n && (v[e].is_ascii_digit() || b".-eE+".contains(&v[e])) {
                        e += 1;
                    }
                    v.splice(s..e, HOSTILE[rng.below(HOSTILE.len())].bytes());
                }
            }
            7 if n > 0 => v.truncate(rng.below(n)),
            _ => {
                // Duplicate a whole line (repeated keys, tables, faces).
                let lines: Vec<Vec<u8>> = v.split(|b| *b == b'\n').map(<[u8]>::to_vec).collect();
                let l = &lines[rng.below(lines.len())];
                let mut piece = l.clone();
                piece.push(b'\n');
                let at = rng.below(v.len() + 1);
                v.splice(at..at, piece);
            }
        }
    }
    v
}

/// Runs one input through its reader. `Ok(true)`: accepted; `Ok(false)`: rejected
/// with an error.
fn run_one(target: Target, input: &[u8], scratch: &Path) -> Result<bool> {
    let text = String::from_utf8_lossy(input);
    let r = match target {
        Target::Scene => {
            let p = scratch.join("fuzz-scene.toml");
            std::fs::write(&p, input)?;
            crate::scene::loader::load_scene(&p).map(|_| ())
        }
        Target::Obj => parse_obj(&text, &scratch.join("fuzz.obj")).map(|_| ()),
        Target::Mtl => parse_mtl(&text, &scratch.join("fuzz.mtl")).map(|_| ()),
        Target::Manifest => Manifest::parse(&text, &scratch.join("fuzz-manifest.toml"), scratch).map(|_| ()),
        Target::Xml => {
            let p = scratch.join("fuzz-scene.xml");
            crate::scene::mitsuba::xml::parse_text(&text, &p).and_then(|doc| crate::scene::mitsuba::build(&doc, &p)).map(|_| ())
        }
        Target::Ply => crate::scene::ply::parse_ply(input, &scratch.join("fuzz.ply")).map(|_| ()),
        Target::Serialized => {
            use crate::scene::serialized::{parse_serialized, wrap_payloads};
            let _ = parse_serialized(input, 0);
            let _ = parse_serialized(input, 1);
            parse_serialized(&wrap_payloads(&[input.to_vec()]), 0).map(|_| ())
        }
        // PIZ-compressed EXR is skipped: the exr crate's PIZ decoder allocates what a
        // corrupt Huffman table asks for and aborts (not a panic) — a known limit.
        Target::Image if image_kind(input) == "exr" && exr_is_piz(input) => Err(anyhow::anyhow!("PIZ EXR not fuzzed")),
        Target::Image => crate::texture::Image::decode(input, image_kind(input), false).map(|_| ()),
    };
    Ok(r.is_ok())
}

/// Seed files: the built-in scenes exported (TOML + OBJ + MTL), the shipped
/// manifests, and the extra corpus directories.
fn seeds(scratch: &Path, extra: &[PathBuf]) -> Result<Vec<(Target, Vec<u8>)>> {
    let mut files: Vec<PathBuf> = Vec::new();
    for name in ["cornell", "cornell-glass", "furnace"] {
        let scene = crate::scene::builtin::builtin(name)?;
        let d = scratch.join(format!("seed-{name}"));
        crate::scene::export::export_scene(&scene, &d)?;
        files.extend(walk(&d));
    }
    let exp = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    files.extend(walk(&exp).into_iter().filter(|p| p.parent() == Some(exp.as_path())));
    // Mitsuba scenes without spheres (a tessellated sphere makes an input slow), and
    // their assets.
    files.extend(["mi-interior.xml", "mi-textured.xml"].iter().map(|n| exp.join("scenes").join(n)).filter(|p| p.is_file()));
    files.extend(walk(&exp.join("scenes").join("mitsuba")));
    for d in extra {
        files.extend(walk(d));
    }
    let mut out = vec![(Target::Xml, XML_SEED.as_bytes().to_vec()), (Target::Ply, PLY_SEED.as_bytes().to_vec())];
    {
        use crate::scene::serialized::{mesh_payload, write_serialized};
        use glam::{Vec2, Vec3};
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        let (n, uv) = ([Vec3::Z; 4], [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE]);
        let quad: crate::scene::serialized::MeshSlices = (&p, &n, &uv, &[[0, 1, 2], [1, 3, 2]]);
        out.push((Target::Serialized, write_serialized(&[(&p[..3], &[], &[], &[[0, 1, 2]]), quad])));
        out.push((Target::Serialized, mesh_payload(&quad, "quad")));
    }
    // A 16x8 baseline JPEG (a gradient, written once with Pillow), so the image target
    // mutates real JPEG markers without a JPEG encoder in the binary.
    out.push((Target::Image, include_bytes!("../assets/fuzz/seed.jpg").to_vec()));
    for f in files {
        let target = match f.extension().and_then(|e| e.to_str()) {
            Some("obj") => Target::Obj,
            Some("mtl") => Target::Mtl,
            Some("xml") => Target::Xml,
            Some("ply") => Target::Ply,
            Some("serialized") => Target::Serialized,
            Some("png" | "jpg" | "jpeg" | "exr") => Target::Image,
            Some("toml") => {
                let t = std::fs::read_to_string(&f).unwrap_or_default();
                if t.contains("[camera]") { Target::Scene } else { Target::Manifest }
            }
            _ => continue,
        };
        // The scratch directory holds the exported meshes, so scene seeds find them.
        let bytes = std::fs::read(&f).with_context(|| format!("{}: cannot read", f.display()))?;
        out.push((target, bytes));
    }
    if out.is_empty() {
        bail!("no seed files");
    }
    Ok(out)
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir(dir) else { return out };
    let mut entries: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// Fuzzes the readers; see the module documentation.
pub fn fuzz(args: &FuzzArgs) -> Result<FuzzReport> {
    // Scene inputs go through a file: on tmpfs where there is one (writing 10^5 files
    // to a busy disk is throttled to a crawl).
    let shm = Path::new("/dev/shm");
    let scratch = if shm.is_dir() { shm.join(format!("photonlab-fuzz-{}", std::process::id())) } else { args.out.join("scratch") };
    std::fs::create_dir_all(&scratch).with_context(|| format!("{}: cannot create", scratch.display()))?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("{}: cannot create", args.out.display()))?;
    let seeds = seeds(&scratch, &args.corpus)?;
    // Scene seeds name their meshes relative to their own directory: give the
    // mutated scene file the same neighbours by copying the exported meshes.
    for e in walk(&scratch) {
        if matches!(e.extension().and_then(|x| x.to_str()), Some("obj" | "mtl"))
            && let Some(name) = e.file_name()
        {
            std::fs::copy(&e, scratch.join(name)).ok();
        }
    }
    // XML seeds name their assets (and includes) relative to experiments/scenes.
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments").join("scenes");
    std::fs::create_dir_all(scratch.join("mitsuba")).ok();
    for e in walk(&scenes.join("mitsuba")) {
        if let Some(name) = e.file_name() {
            std::fs::copy(&e, scratch.join("mitsuba").join(name)).ok();
        }
    }
    std::fs::copy(scenes.join("mi-interior-materials.xml"), scratch.join("mi-interior-materials.xml")).ok();
    let mut rng = Rng(args.seed);
    let last_panic: Arc<Mutex<String>> = Arc::new(Mutex::new(String::new()));
    let lp = last_panic.clone();
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        *lp.lock().unwrap_or_else(|e| e.into_inner()) = info.to_string();
    }));
    // Watchdog: if the counter does not move for `timeout`, save the input being run
    // as `hang.bin`, report it and stop.
    let counter = Arc::new(AtomicU64::new(0));
    let current: Arc<Mutex<Vec<u8>>> = Arc::new(Mutex::new(Vec::new()));
    let (c2, cur2, out2, timeout) = (counter.clone(), current.clone(), args.out.clone(), Duration::from_secs(args.timeout.max(1)));
    std::thread::spawn(move || {
        let mut last = (u64::MAX, Instant::now());
        loop {
            std::thread::sleep(Duration::from_millis(200));
            let n = c2.load(Ordering::Relaxed);
            if n != last.0 {
                last = (n, Instant::now());
            } else if last.1.elapsed() > timeout {
                let p = out2.join("hang.bin");
                // The main thread holds no lock while it runs an input.
                let _ = std::fs::write(&p, &*cur2.lock().unwrap_or_else(|e| e.into_inner()));
                eprintln!("fuzz: input {n} ran for more than {timeout:?}: a hang; saved as {}", p.display());
                std::process::exit(3);
            }
        }
    });
    let t0 = Instant::now();
    let mut rep = FuzzReport::default();
    let bodies: Vec<&[u8]> = seeds.iter().map(|s| s.1.as_slice()).collect();
    for i in 0..args.inputs {
        let (target, seed) = &seeds[rng.below(seeds.len())];
        let same: Vec<&[u8]> = seeds.iter().filter(|s| s.0 == *target).map(|s| s.1.as_slice()).collect();
        let input = if rng.below(10) == 0 {
            let n = rng.below(512);
            (0..n).map(|_| rng.next() as u8).collect()
        } else if rng.below(4) == 0 {
            mutate(seed, &bodies, &mut rng)
        } else {
            mutate(seed, &same, &mut rng)
        };
        current.lock().unwrap_or_else(|e| e.into_inner()).clone_from(&input);
        counter.store(i, Ordering::Relaxed);
        let t_in = Instant::now();
        let result = std::panic::catch_unwind(|| run_one(*target, &input, &scratch));
        let dt = t_in.elapsed().as_secs_f64();
        if dt > rep.slowest.0 {
            rep.slowest = (dt, Some(*target));
            rep.slowest_input.clone_from(&input);
        }
        match result {
            Ok(Ok(true)) => rep.ok += 1,
            Ok(_) => rep.errors += 1,
            Err(_) => {
                let p = args.out.join(format!("panic-{i}-{target:?}.bin").to_lowercase());
                std::fs::write(&p, &input).ok();
                let msg = last_panic.lock().map(|m| m.clone()).unwrap_or_default();
                eprintln!("fuzz: PANIC on input {i} ({target:?}), saved as {}: {msg}", p.display());
                rep.panics.push(p);
            }
        }
        rep.inputs += 1;
    }
    counter.store(u64::MAX - 1, Ordering::Relaxed);
    std::panic::set_hook(previous_hook);
    if scratch.starts_with(shm) {
        std::fs::remove_dir_all(&scratch).ok();
    }
    rep.seconds = t0.elapsed().as_secs_f64();
    std::fs::write(args.out.join("slowest.bin"), &rep.slowest_input).ok();
    Ok(rep)
}

/// `photonlab fuzz`.
pub fn fuzz_cmd(args: &FuzzArgs) -> Result<()> {
    let r = fuzz(args)?;
    outln!(
        "fuzz: {} inputs in {:.1} s: {} accepted, {} rejected with an error, {} panics, no hang (timeout {} s; slowest input {:.3} s, {:?})",
        r.inputs,
        r.seconds,
        r.ok,
        r.errors,
        r.panics.len(),
        args.timeout,
        r.slowest.0,
        r.slowest.1
    );
    if !r.panics.is_empty() {
        bail!("{} inputs panicked; saved under {}", r.panics.len(), args.out.display());
    }
    Ok(())
}
