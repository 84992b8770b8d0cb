//! The documented Slurm workflow on a real Slurm cluster (`experiments/slurm/local-cluster.sh`:
//! Debian's slurm-wlm, one node, four task slots): reference parts as an array →
//! shards as an array (afterok) → merge (afterok), for `experiments/quick.toml`, with
//! one shard task killed mid-run and requeued. The merged `cells.csv` and
//! `summary.md` must equal a single-machine run's up to timing columns, the
//! reference must be the same bits, and no cell or reference part may be rendered twice.
//!
//! Needs root (to start munged, slurmctld and slurmd, and to install them when
//! missing). Under CI (`CI` set) a cluster that cannot be brought up fails the test;
//! elsewhere the test is skipped with a message on stderr.
//! `PHOTONLAB_SLURM_MANIFEST` replaces the manifest (default `experiments/quick.toml`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_photonlab");
const TASKS: usize = 4;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn slurm_dir() -> PathBuf {
    std::env::var_os("PHOTONLAB_SLURM_DIR").map_or_else(|| PathBuf::from("/tmp/photonlab-slurm"), PathBuf::from)
}

fn conf() -> PathBuf {
    slurm_dir().join("etc/slurm.conf")
}

fn sh(cmd: &str, args: &[&str]) -> Output {
    Command::new(cmd).args(args).env("SLURM_CONF", conf()).current_dir(repo()).output().unwrap_or_else(|e| panic!("{cmd}: {e}"))
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn cluster(cmd: &str) -> Output {
    sh("bash", &["experiments/slurm/local-cluster.sh", cmd])
}

/// Stops the cluster however the test ends.
struct Down;
impl Drop for Down {
    fn drop(&mut self) {
        let o = cluster("down");
        eprintln!("{}", text(&o));
    }
}

/// One test at a time may own the machine's cluster (cargo runs tests in parallel,
/// and other worktrees may run this suite): an exclusive lock held until dropped.
struct Lock(#[allow(dead_code)] std::fs::File);
fn lock() -> Lock {
    use std::os::fd::AsRawFd;
    let f = std::fs::File::create(std::env::temp_dir().join("photonlab-slurm.lock")).unwrap();
    // SAFETY: flock on a file descriptor we own; blocks until the lock is free.
    assert_eq!(unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) }, 0);
    Lock(f)
}

fn scontrol_field(job: &str, field: &str) -> String {
    let o = sh("scontrol", &["show", "job", job]);
    let t = text(&o);
    t.split_whitespace().find_map(|kv| kv.strip_prefix(&format!("{field}="))).unwrap_or("").to_string()
}

fn wait_for(what: &str, secs: u64, logs: &Path, mut done: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !done() {
        if t0.elapsed() > Duration::from_secs(secs) {
            let mut all = String::new();
            for e in std::fs::read_dir(logs).into_iter().flatten().flatten() {
                all += &format!("== {}\n{}\n", e.path().display(), std::fs::read_to_string(e.path()).unwrap_or_default());
            }
            panic!("timed out after {secs} s waiting for {what}\n{}\n{all}", text(&sh("squeue", &[])));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// cells.csv as header + rows keyed by cell, without timing columns (`*_s`) and the thread count.
fn csv(dir: &Path) -> BTreeMap<String, Vec<(String, String)>> {
    let t = std::fs::read_to_string(dir.join("cells.csv")).unwrap();
    let mut lines = t.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            let row: Vec<&str> = l.split(',').collect();
            let kept = header.iter().zip(&row).filter(|(h, _)| !h.ends_with("_s") && **h != "threads");
            (row[0].to_string(), kept.map(|(h, v)| (h.to_string(), v.to_string())).collect())
        })
        .collect()
}

/// summary.md without what depends on measured times: sections about time or
/// choosing by time, and table columns whose header names a time.
fn summary(dir: &Path) -> Vec<String> {
    let t = std::fs::read_to_string(dir.join("summary.md")).unwrap();
    let mut out = Vec::new();
    let (mut skip, mut in_table, mut drop_cols) = (false, false, Vec::new());
    for line in t.lines() {
        if line.starts_with('#') {
            let l = line.to_lowercase();
            skip = l.contains("time") || l.contains("budget");
        }
        if skip {
            continue;
        }
        if !line.starts_with('|') {
            in_table = false;
            out.push(line.to_string());
            continue;
        }
        let cells: Vec<&str> = line.split('|').collect();
        if !in_table {
            in_table = true;
            let timed = |c: &str| c.to_lowercase().contains("time") || c.contains("(s)");
            drop_cols = cells.iter().enumerate().filter(|(_, c)| timed(c)).map(|(i, _)| i).collect();
        }
        out.push(cells.iter().enumerate().filter(|(i, _)| !drop_cols.contains(i)).map(|(_, c)| *c).collect::<Vec<_>>().join("|"));
    }
    out
}

fn exr_bits(p: &Path) -> Vec<u32> {
    let f = photonlab::film::Film::read_exr(p).unwrap();
    f.pixels.iter().flat_map(|c| c.to_array()).map(f32::to_bits).collect()
}

/// Lines `  STEM: RMSE …` (one per cell rendered to the end) and reference parts rendered, over logs.
fn rendered(logs: &[PathBuf]) -> (BTreeMap<String, usize>, BTreeMap<String, usize>) {
    let (mut cells, mut parts) = (BTreeMap::new(), BTreeMap::new());
    for p in logs {
        for l in std::fs::read_to_string(p).unwrap().lines() {
            if let Some((stem, _)) = l.strip_prefix("  ").and_then(|l| l.split_once(": RMSE ")) {
                *cells.entry(stem.to_string()).or_insert(0) += 1;
            }
            if let Some(r) = l.strip_prefix("rendering reference samples ") {
                *parts.entry(r.split(' ').next().unwrap().to_string()).or_insert(0) += 1;
            }
        }
    }
    (cells, parts)
}

fn logs(dir: &Path, prefix: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix))
        .collect();
    v.sort();
    v
}

#[test]
fn slurm_workflow_with_a_requeued_shard_equals_a_single_machine_run() {
    let _lock = lock();
    let up = cluster("up");
    if !up.status.success() {
        let why = text(&up);
        if std::env::var_os("CI").is_some() {
            panic!("CI: the local Slurm cluster did not come up:\n{why}");
        }
        eprintln!("SKIPPED slurm_workflow…: no local Slurm cluster (needs root and slurm-wlm/munge or apt-get):\n{why}");
        return;
    }
    let _down = Down;
    let manifest = std::env::var("PHOTONLAB_SLURM_MANIFEST").unwrap_or_else(|_| "experiments/quick.toml".into());
    let d = std::env::temp_dir().join(format!("photonlab-slurm-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    let (single, sharded) = (d.join("single/exp"), d.join("slurm/exp"));

    // The single-machine run (its own reference cache, d/single/references).
    let t0 = Instant::now();
    let o = Command::new(BIN).args(["run", &manifest, "--quiet", "--out"]).arg(&single).current_dir(repo()).output().unwrap();
    assert!(o.status.success(), "single-machine run failed: {}", text(&o));
    eprintln!("single-machine run: {:.1} s", t0.elapsed().as_secs_f64());

    let shard2 = Command::new(BIN)
        .args(["run", &manifest, "--list", "--shard", &format!("2/{TASKS}"), "--out"])
        .arg(&sharded)
        .current_dir(repo())
        .output()
        .unwrap();
    // The workflow, as documented: submit.sh = reference array → shard array → merge.
    let t0 = Instant::now();
    let o = Command::new("bash")
        .args(["experiments/slurm/submit.sh", &manifest, &TASKS.to_string(), "--out"])
        .arg(&sharded)
        .env("SLURM_CONF", conf())
        .env("PHOTONLAB", BIN)
        .env("PHOTONLAB_SBATCH_ARGS", "--cpus-per-task=1")
        .current_dir(repo())
        .output()
        .unwrap();
    assert!(o.status.success(), "submit.sh failed: {}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let ids: Vec<&str> = out.lines().last().unwrap().strip_prefix("jobs ").unwrap().split(' ').collect();
    let (refs, shards, merge) = (ids[0], ids[1], ids[2]);
    let logdir = sharded.join("logs");

    // Kill shard 2 as soon as its first cell is recorded (mid-run: more cells follow), requeue it.
    let stems: Vec<String> = String::from_utf8_lossy(&shard2.stdout)
        .lines()
        .filter(|l| l.contains("to run"))
        .filter_map(|l| l.split_whitespace().nth(3).map(str::to_string))
        .collect();
    assert!(stems.len() >= 2, "shard 2 needs two cells to be killed between them: {}", text(&shard2));
    let first = sharded.join("cells").join(format!("{}.json", stems[0]));
    wait_for("shard 2's first cell", 900, &logdir, || first.exists());
    let victim = format!("{shards}_2");
    let o = sh("scontrol", &["requeue", &victim]);
    assert!(o.status.success(), "requeue: {}", text(&o));
    let last = sharded.join("cells").join(format!("{}.json", stems[stems.len() - 1]));
    assert!(!last.exists(), "shard 2 finished before it was killed; the test needs a slower manifest");
    eprintln!("requeued {victim} after {:.1} s, while it rendered its second cell", t0.elapsed().as_secs_f64());
    // A requeued job waits until its revoked credential expires (AuthInfo cred_expire,
    // 10 s on the local cluster) before it starts again. Forcing it to start earlier
    // (StartTime=now) gets it killed as "Job credential revoked" and the merge job's
    // dependency is then never satisfied, so the test lets Slurm start it.
    wait_for("the requeued task to be pending", 120, &logdir, || scontrol_field(&victim, "JobState") == "PENDING");

    wait_for("the merge job", 900, &logdir, || {
        let q = sh("squeue", &["-h", "-j", &format!("{refs},{shards},{merge}"), "-o", "%i"]);
        q.status.success() && q.stdout.iter().all(u8::is_ascii_whitespace)
    });
    eprintln!("slurm workflow: {:.1} s", t0.elapsed().as_secs_f64());
    assert_eq!(scontrol_field(merge, "JobState"), "COMPLETED", "merge job: {}", text(&sh("scontrol", &["show", "job", merge])));
    assert_eq!(scontrol_field(&victim, "Restarts"), "1");

    // Same results as the single machine, the reference bit for bit.
    let (a, b) = (csv(&single), csv(&sharded));
    assert!(a.len() >= 2 * TASKS && a.keys().eq(b.keys()), "{:?} vs {:?}", a.keys(), b.keys());
    for (cell, row) in &a {
        assert_eq!(row, &b[cell], "{cell}");
    }
    let (sa, sb) = (summary(&single), summary(&sharded));
    assert!(sa.len() > 20);
    for (x, y) in sa.iter().zip(&sb) {
        assert_eq!(x, y, "summary.md differs");
    }
    assert_eq!(sa.len(), sb.len());
    let reference = |dir: &Path| {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.file_name().unwrap().to_string_lossy().starts_with("reference-") && p.extension().is_some_and(|e| e == "exr"))
    };
    assert_eq!(exr_bits(&reference(&single).unwrap()), exr_bits(&reference(&sharded).unwrap()), "reference images differ");
    // Threads = the CPUs Slurm gave each task.
    let t = std::fs::read_to_string(sharded.join("cells.csv")).unwrap();
    let col = t.lines().next().unwrap().split(',').position(|h| h == "threads").unwrap();
    assert!(t.lines().skip(1).all(|l| l.split(',').nth(col) == Some("1")), "threads column is not 1");

    // Every reference part and every cell rendered exactly once, in the logs of both attempts.
    let (cells, _) = rendered(&logs(&sharded, "shard-"));
    assert_eq!(cells.keys().collect::<Vec<_>>(), a.keys().collect::<Vec<_>>());
    assert!(cells.values().all(|&n| n == 1), "a cell was rendered twice: {cells:?}");
    let (_, parts) = rendered(&logs(&sharded, "reference-"));
    assert_eq!(parts.len(), TASKS, "{parts:?}");
    assert!(parts.values().all(|&n| n == 1), "{parts:?}");
    assert!(rendered(&logs(&sharded, "shard-")).1.is_empty(), "a shard rendered reference samples");
    let victim_log = std::fs::read_to_string(logdir.join(format!("shard-{shards}_2.out"))).unwrap();
    assert!(victim_log.contains("restart 0") && victim_log.contains("restart 1"), "{victim_log}");
    let second = victim_log.split("restart 1").nth(1).unwrap();
    let kept: usize = second.split(" already finished").next().and_then(|s| s.rsplit(' ').next()).and_then(|n| n.parse().ok()).unwrap_or(0);
    assert!(kept >= 1 && kept < stems.len(), "the requeued task should keep its finished cells: {victim_log}");
    assert!(!second.contains(&format!("  {}: RMSE", stems[0])), "the finished cell was rendered again");
    std::fs::remove_dir_all(&d).ok();
}

/// The job script refuses what would silently go wrong.
#[test]
fn shard_script_refuses_to_run_outside_an_array_or_on_an_unshared_directory() {
    let run = |env: &[(&str, &str)]| {
        let mut c = Command::new("bash");
        c.args(["experiments/slurm/shard.sbatch", "experiments/quick.toml"]).current_dir(repo()).env("PHOTONLAB", BIN);
        for k in ["SLURM_JOB_ID", "SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT", "PHOTONLAB_SUBMIT_TOKEN", "PHOTONLAB_UNSHARED"] {
            c.env_remove(k);
        }
        c.envs(env.iter().copied());
        let o = c.output().unwrap();
        (o.status.code(), text(&o))
    };
    let (code, t) = run(&[]);
    assert!(code == Some(2) && t.contains("not running under Slurm"), "{t}");
    let (code, t) = run(&[("SLURM_JOB_ID", "7")]);
    assert!(code == Some(2) && t.contains("not an array task"), "{t}");
    let array = [("SLURM_JOB_ID", "7"), ("SLURM_ARRAY_TASK_ID", "3"), ("SLURM_ARRAY_TASK_COUNT", "2")];
    let (code, t) = run(&[array.as_slice(), &[("SLURM_ARRAY_TASK_MIN", "3"), ("SLURM_ARRAY_TASK_MAX", "4")]].concat());
    assert!(code == Some(2) && t.contains("must be 1..N"), "{t}");
    let d = std::env::temp_dir().join(format!("photonlab-unshared-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join(".slurm-submit-token"), "written-on-another-node\n").unwrap();
    let ok = [("SLURM_JOB_ID", "7"), ("SLURM_ARRAY_TASK_ID", "1"), ("SLURM_ARRAY_TASK_COUNT", "2"), ("SLURM_ARRAY_TASK_MIN", "1")];
    let env = [ok.as_slice(), &[("SLURM_ARRAY_TASK_MAX", "2"), ("PHOTONLAB_SUBMIT_TOKEN", "mine"), ("PHOTONLAB_OUT", d.to_str().unwrap())]]
        .concat();
    let (code, t) = run(&env);
    assert!(code == Some(2) && t.contains("not shared") && t.contains("photonlab merge"), "{t}");
    std::fs::remove_dir_all(&d).ok();
}

/// `render --sample-range` + `accumulate` through the command line: 4 parts and 2 parts
/// give byte-identical files; bad parts are errors with a non-zero exit.
#[test]
fn accumulated_parts_are_byte_identical_files_for_any_split() {
    let d = std::env::temp_dir().join(format!("photonlab-parts-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let render = |range: &str, out: &str| {
        let o = Command::new(BIN)
            .args(["render", "--resolution", "20x20", "--spp", "8", "--quiet", "--sample-range", range, "-o"])
            .arg(d.join(out))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", text(&o));
    };
    for (r, o) in [("0..2", "a"), ("2..4", "b"), ("4..6", "c"), ("6..8", "d"), ("0..4", "e"), ("4..8", "f")] {
        render(r, o);
    }
    let acc = |out: &str, parts: &[&str]| {
        let mut c = Command::new(BIN);
        c.arg("accumulate").arg(d.join(out));
        for p in parts {
            c.arg(d.join(p));
        }
        c.output().unwrap()
    };
    assert!(acc("four.exr", &["d.psum", "a.psum", "c.exr", "b.psum"]).status.success());
    assert!(acc("two.exr", &["e.psum", "f.psum"]).status.success());
    let (four, two) = (std::fs::read(d.join("four.exr")).unwrap(), std::fs::read(d.join("two.exr")).unwrap());
    assert!(four.len() > 1000 && four == two, "4-part and 2-part EXR files differ");
    let o = acc("bad.exr", &["a.psum", "e.psum", "f.psum"]);
    assert!(o.status.code() == Some(1) && text(&o).contains("overlap") && text(&o).contains("e.psum"), "{}", text(&o));
    let o = acc("bad.exr", &["a.psum", "f.psum"]);
    assert!(o.status.code() == Some(1) && text(&o).contains("samples 2..4 of 8 are in no part"), "{}", text(&o));
    std::fs::write(d.join("junk.psum"), "not a part").unwrap();
    let o = acc("bad.exr", &["junk.psum"]);
    assert!(o.status.code() == Some(1) && text(&o).contains("junk.psum: not a photonlab sample-range part"), "{}", text(&o));
    let o = Command::new(BIN).args(["render", "--spp", "8", "--sample-range", "4..9", "-o"]).arg(d.join("x")).output().unwrap();
    assert!(o.status.code() == Some(1) && text(&o).contains("not inside the render's 8 samples"), "{}", text(&o));
    std::fs::remove_dir_all(&d).ok();
}
