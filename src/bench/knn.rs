//! `photonlab bench knn`: the photon kd-tree against `kiddo` on the same points, in one
//! process, so every figure is a ratio measured side by side.
//!
//! Two point sets of `--n` points: uniform in the unit cube, and uniform on the six
//! faces of the unit box (photons on walls). For each, both trees are built (timed),
//! then the same query points (drawn from the same distribution) are answered with
//! k = 50, 100, 200 nearest neighbours and with k = 100 within a radius that holds
//! about 50 points on average, on 1 and 2 threads. The results of both trees are
//! compared query by query (same neighbour sets; ties at the k-th distance aside).
//!
//! kiddo is an optional dependency behind the `kiddo` cargo feature (off by default, so
//! that a first build does not compile it);
//! without it the command says how to enable it.

use anyhow::Result;
use clap::Args;

/// Flags of `bench knn`.
#[derive(Args, Debug, Clone)]
pub struct KnnArgs {
    /// Points per tree.
    #[arg(long, default_value_t = 1_000_000)]
    pub n: usize,
    /// Query points per measurement.
    #[arg(long, default_value_t = 20_000)]
    pub queries: usize,
    /// Run with this many threads only (default: 1 and 2).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Timed repetitions of each measurement (own and kiddo alternate; the fastest
    /// of each counts, which damps the load of a shared machine).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Runs `bench knn`.
#[cfg(not(feature = "kiddo"))]
pub fn run(_args: &KnnArgs) -> Result<()> {
    anyhow::bail!(
        "bench knn compares with the kiddo crate, which this build leaves out: rebuild with the `kiddo` feature \
         (`cargo run --release --features kiddo -- bench knn`)"
    )
}

/// Runs `bench knn`.
#[cfg(feature = "kiddo")]
pub fn run(args: &KnnArgs) -> Result<()> {
    imp::run(args)
}

#[cfg(feature = "kiddo")]
mod imp {
    use super::KnnArgs;
    use crate::math::{Color, hash_words, u32_to_unit};
    use crate::photon::kdtree::{KdTree, KnnHeap};
    use crate::photon::record::Photon;
    use crate::pipeline::thread_pool;
    use anyhow::{Context, Result, bail};
    use glam::Vec3;
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    use rayon::prelude::*;
    use std::num::NonZero;
    use std::time::Instant;

    type Kiddo = ImmutableKdTree<f32, 3>;

    /// Point distributions.
    #[derive(Clone, Copy, Debug)]
    enum Dist {
        Cube,
        Faces,
    }

    impl Dist {
        fn name(self) -> &'static str {
            match self {
                Dist::Cube => "cube",
                Dist::Faces => "faces",
            }
        }

        /// Point `i` of stream `stream` and its surface normal.
        fn point(self, stream: u64, i: u64) -> (Vec3, Vec3) {
            let r = |j: u64| u32_to_unit(hash_words(&[stream, i, j]) as u32);
            let mut p = Vec3::new(r(0), r(1), r(2));
            match self {
                Dist::Cube => (p, Vec3::Z),
                Dist::Faces => {
                    let a = (hash_words(&[stream, i, 3]) % 6) as usize;
                    let side = if a >= 3 { 1.0 } else { 0.0 };
                    p[a % 3] = side;
                    let mut n = Vec3::ZERO;
                    n[a % 3] = if side > 0.5 { -1.0 } else { 1.0 };
                    (p, n)
                }
            }
        }

        /// A radius holding about `count` of `n` points on average.
        fn radius_for(self, n: usize, count: f32) -> f32 {
            match self {
                // Ball volume 4/3 π r³ in the unit cube.
                Dist::Cube => (3.0 * count / (4.0 * std::f32::consts::PI * n as f32)).cbrt(),
                // Disc area π r² on 6 unit faces.
                Dist::Faces => (6.0 * count / (std::f32::consts::PI * n as f32)).sqrt(),
            }
        }
    }

    /// One query kind.
    #[derive(Clone, Copy, Debug)]
    struct Op {
        k: usize,
        radius: Option<f32>,
    }

    impl Op {
        fn label(&self) -> String {
            match self.radius {
                None => format!("k={}", self.k),
                Some(_) => format!("k={} r", self.k),
            }
        }
    }

    /// A measured row: own and kiddo seconds for one (distribution, op, threads).
    #[derive(serde::Serialize)]
    struct Row {
        bench: &'static str,
        dist: &'static str,
        op: String,
        k: Option<usize>,
        radius: Option<f32>,
        threads: usize,
        n: usize,
        queries: usize,
        own_s: f64,
        kiddo_s: f64,
        /// own time / kiddo time (< 1: own is faster).
        ratio: f64,
        own_ns_per_query: Option<f64>,
        kiddo_ns_per_query: Option<f64>,
        own_bytes_per_point: f64,
        kiddo_bytes_per_point: f64,
        /// Queries whose neighbour sets differ (ties aside); None for build rows.
        mismatches: Option<usize>,
        /// 1-minute load average when the row was measured.
        load_average: Option<f64>,
    }

    /// Bytes held by kiddo's immutable tree, from its layout (kiddo reports no size):
    /// per point 3 × f32 and a u32 item in the leaf arena, per leaf an extent of two
    /// usize, per stem one f32 split (stem count from its `Debug` output, which
    /// reports it; else one stem per leaf).
    fn kiddo_bytes(t: &Kiddo) -> usize {
        let dbg = format!("{t:?}");
        let stems = dbg
            .find("stem_count: ")
            .and_then(|at| dbg[at + 12..].split(|c: char| !c.is_ascii_digit()).next()?.parse().ok())
            .unwrap_or(t.leaf_count());
        t.size() * 16 + t.leaf_count() * 2 * std::mem::size_of::<usize>() + stems * 4
    }

    fn own_query(tree: &KdTree<Photon>, q: Vec3, op: Op, heap: &mut KnnHeap) -> usize {
        let r2 = op.radius.map_or(f32::INFINITY, |r| r * r);
        tree.knn(q, op.k, r2, heap, &|_, _| true);
        heap.items.len()
    }

    fn kiddo_query(tree: &Kiddo, q: Vec3, op: Op) -> Vec<(f32, u32)> {
        let k = NonZero::new(op.k.max(1)).unwrap_or(NonZero::<usize>::MIN);
        let q = q.to_array();
        let res = match op.radius {
            None => tree.query(&q).nearest_n::<SquaredEuclidean<f32>>(k).unsorted().execute(),
            Some(r) => tree.query(&q).nearest_n::<SquaredEuclidean<f32>>(k).within(r * r).exclusive_boundaries().unsorted().execute(),
        };
        res.into_iter().map(|x| (x.distance, x.item)).collect()
    }

    /// Same neighbours: equal counts, and every point of one result that is not in
    /// the other lies at the k-th distance (a tie).
    fn same_neighbours(own: &[(f32, Vec3)], kid: &[(f32, Vec3)]) -> bool {
        if own.len() != kid.len() {
            return false;
        }
        let key = |p: Vec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        let mut a: Vec<_> = own.iter().map(|&(d, p)| (key(p), d)).collect();
        let mut b: Vec<_> = kid.iter().map(|&(d, p)| (key(p), d)).collect();
        a.sort_by_key(|x| x.0);
        b.sort_by_key(|x| x.0);
        let dmax = own.iter().chain(kid).map(|x| x.0).fold(0.0f32, f32::max);
        let tol = 1e-5 * dmax.max(1e-30);
        let only = |x: &[((u32, u32, u32), f32)], y: &[((u32, u32, u32), f32)]| {
            x.iter().filter(|e| y.binary_search_by_key(&e.0, |f| f.0).is_err()).all(|e| e.1 >= dmax - tol)
        };
        only(&a, &b) && only(&b, &a)
    }

    fn time<R>(f: impl FnOnce() -> R) -> (R, f64) {
        let t = Instant::now();
        let r = f();
        (r, t.elapsed().as_secs_f64())
    }

    pub fn run(args: &KnnArgs) -> Result<()> {
        if args.n == 0 || args.queries == 0 {
            bail!("bench knn: --n and --queries must be at least 1");
        }
        let threads: Vec<usize> = match args.threads {
            Some(0) => bail!("bench knn: --threads must be at least 1"),
            Some(t) => vec![t],
            None => vec![1, 2],
        };
        let mut rows = Vec::new();
        let mut failed = Vec::new();
        for dist in [Dist::Cube, Dist::Faces] {
            let pts: Vec<(Vec3, Vec3)> = (0..args.n as u64).map(|i| dist.point(1, i)).collect();
            let queries: Vec<Vec3> = (0..args.queries as u64).map(|i| dist.point(2, i).0).collect();
            let positions: Vec<Vec3> = pts.iter().map(|x| x.0).collect();
            let photons: Vec<Photon> = pts.iter().map(|&(_, n)| Photon::new(Color::splat(1e-6), n, n)).collect();
            let mut own = None;
            let mut kid = None;
            for &t in &threads {
                let pool = thread_pool(t)?;
                let (mut own_s, mut kiddo_s) = (f64::INFINITY, f64::INFINITY);
                let mut built = None;
                for _ in 0..args.reps.max(1) {
                    drop(built.take());
                    let photons = photons.clone();
                    let (o, s) = pool.install(|| time(|| KdTree::build_with(&positions, photons)));
                    own_s = own_s.min(s);
                    // kiddo gets the points exactly as the own tree stores them
                    // (quantised), in the original order.
                    let kpts: Vec<[f32; 3]> = positions.iter().map(|&p| o.stored_position(p).to_array()).collect();
                    let (k, s) = pool.install(|| time(|| Kiddo::new_from_slice(&kpts)));
                    kiddo_s = kiddo_s.min(s);
                    built = Some((o, kpts, k.map_err(|e| anyhow::anyhow!("kiddo build: {e:?}"))?));
                }
                let (o, kpts, k) = built.context("no repetition")?;
                rows.push(Row {
                    bench: "knn",
                    dist: dist.name(),
                    op: "build".into(),
                    k: None,
                    radius: None,
                    threads: t,
                    n: args.n,
                    queries: 0,
                    own_s,
                    kiddo_s,
                    ratio: own_s / kiddo_s,
                    own_ns_per_query: None,
                    kiddo_ns_per_query: None,
                    own_bytes_per_point: o.memory_bytes() as f64 / o.len() as f64,
                    kiddo_bytes_per_point: kiddo_bytes(&k) as f64 / k.size().max(1) as f64,
                    mismatches: None,
                    load_average: crate::bench::scaling::load_average(),
                });
                own = Some((o, kpts));
                kid = Some(k);
            }
            let (own, kpts) = own.context("no thread count")?;
            let kid = kid.context("no thread count")?;
            let bytes = (own.memory_bytes() as f64 / own.len() as f64, kiddo_bytes(&kid) as f64 / kid.size().max(1) as f64);
            let ops = [
                Op { k: 50, radius: None },
                Op { k: 100, radius: None },
                Op { k: 200, radius: None },
                Op { k: 100, radius: Some(dist.radius_for(args.n, 50.0)) },
            ];
            for op in ops {
                // Correctness first (single-threaded, a bounded number of queries).
                let mut heap = KnnHeap::default();
                let mut mismatches = 0;
                for &q in queries.iter().take(2000) {
                    own_query(&own, q, op, &mut heap);
                    let a: Vec<(f32, Vec3)> = heap.items.iter().map(|&(d, i)| (d, own.position(i as usize))).collect();
                    let b: Vec<(f32, Vec3)> =
                        kiddo_query(&kid, q, op).into_iter().map(|(d, i)| (d, Vec3::from_array(kpts[i as usize]))).collect();
                    if !same_neighbours(&a, &b) {
                        mismatches += 1;
                    }
                }
                if mismatches > 0 {
                    failed.push(format!("{} {}: {mismatches} queries differ", dist.name(), op.label()));
                }
                for &t in &threads {
                    let pool = thread_pool(t)?;
                    let (mut own_s, mut kiddo_s) = (f64::INFINITY, f64::INFINITY);
                    let (mut n_own, mut n_kid) = (0, 0);
                    for _ in 0..args.reps.max(1) {
                        let (n, s) = pool.install(|| {
                            time(|| {
                                queries
                                    .par_iter()
                                    .with_min_len(64)
                                    .map_init(KnnHeap::default, |h, &q| own_query(&own, q, op, h))
                                    .sum::<usize>()
                            })
                        });
                        (n_own, own_s) = (n, own_s.min(s));
                        let (n, s) = pool.install(|| {
                            time(|| queries.par_iter().with_min_len(64).map(|&q| kiddo_query(&kid, q, op).len()).sum::<usize>())
                        });
                        (n_kid, kiddo_s) = (n, kiddo_s.min(s));
                    }
                    if n_own != n_kid {
                        failed.push(format!("{} {} {t} threads: {n_own} vs {n_kid} neighbours in all", dist.name(), op.label()));
                    }
                    let nq = queries.len() as f64;
                    rows.push(Row {
                        bench: "knn",
                        dist: dist.name(),
                        op: op.label(),
                        k: Some(op.k),
                        radius: op.radius,
                        threads: t,
                        n: args.n,
                        queries: queries.len(),
                        own_s,
                        kiddo_s,
                        ratio: own_s / kiddo_s,
                        own_ns_per_query: Some(own_s * 1e9 / nq),
                        kiddo_ns_per_query: Some(kiddo_s * 1e9 / nq),
                        own_bytes_per_point: bytes.0,
                        kiddo_bytes_per_point: bytes.1,
                        mismatches: Some(mismatches),
                        load_average: crate::bench::scaling::load_average(),
                    });
                }
            }
        }
        print_rows(&rows, args.json)?;
        if !failed.is_empty() {
            bail!("bench knn: the trees disagree: {}", failed.join("; "));
        }
        Ok(())
    }

    fn print_rows(rows: &[Row], json: bool) -> Result<()> {
        if json {
            for r in rows {
                outln!("{}", serde_json::to_string(r)?);
            }
            return Ok(());
        }
        if let Some(r) = rows.first() {
            outln!(
                "bench knn: {} points, {} queries; times in ms (build) or ns/query (wall time / queries); ratio = own / kiddo; load average {}",
                r.n,
                rows.iter().map(|r| r.queries).max().unwrap_or(0),
                r.load_average.map_or("unknown".into(), |l| format!("{l:.1}"))
            );
        }
        outln!("| dist | op | threads | own | kiddo | ratio | own B/pt | kiddo B/pt | same |");
        outln!("|---|---|---|---|---|---|---|---|---|");
        for r in rows {
            let (a, b) = match (r.own_ns_per_query, r.kiddo_ns_per_query) {
                (Some(a), Some(b)) => (format!("{a:.0} ns"), format!("{b:.0} ns")),
                _ => (format!("{:.1} ms", r.own_s * 1e3), format!("{:.1} ms", r.kiddo_s * 1e3)),
            };
            let same = match r.mismatches {
                None => "-".to_string(),
                Some(0) => "yes".to_string(),
                Some(m) => format!("NO ({m})"),
            };
            outln!(
                "| {} | {} | {} | {a} | {b} | {:.2} | {:.1} | {:.1} | {same} |",
                r.dist,
                r.op,
                r.threads,
                r.ratio,
                r.own_bytes_per_point,
                r.kiddo_bytes_per_point
            );
        }
        Ok(())
    }
}
