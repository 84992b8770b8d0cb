//! The recursive MIS weights against the heuristic computed from the full path
//! densities, over many random paths: for every technique that can sample a path
//! (connections s = 0 … k, merges at every inner vertex), the weight from the
//! partials equals p_i^β / Σ p_j^β, and the weights sum to one. A planted bug (the
//! two reverse densities of an inner connection swapped) must break the sum. With
//! merging at the first non-delta camera vertex only (`vcm_merge = "first"`) the one
//! merge is at the last non-delta vertex x_j (x_{j+1} … x_{k−1} delta). Paths may have
//! delta (specular) inner vertices: no technique connects or merges there, and each
//! technique samples through them with the same delta factor, taken as 1 in both
//! directions (the partials' specular update).

use super::mis::{
    Factors, Heuristic, Partials, uni_camera, uni_connect, uni_direct, uni_hit, uni_merge, uni_share, w_to_a, weight_camera,
    weight_connect, weight_direct, weight_hit, weight_merge,
};
use crate::camera::Camera;
use crate::material::{Bsdf, Glossy, Lambertian, ShadingPoint};
use crate::math::Color;
use glam::Vec3;
use std::f32::consts::PI;

struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f32 {
        self.0 = crate::math::mix64(self.0.wrapping_add(0x9E37_79B9_7F4A_7C15));
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn v(&mut self) -> Vec3 {
        Vec3::new(self.f() * 2.0 - 1.0, self.f() * 2.0 - 1.0, self.f() * 2.0 - 1.0)
    }
}

/// A random path x0 (on an area light) … x_{k−1}, x_k = the eye.
struct Path {
    x: Vec<Vec3>,
    sp: Vec<ShadingPoint>,
    bsdf: Vec<Bsdf>,
    /// Delta (specular) vertices (never x0).
    delta: Vec<bool>,
    cam: Camera,
    area: f32,
    pick: f32,
}

/// `specular`: share of the inner vertices x1 … x_{k−1} that are delta.
fn random_path(rng: &mut Rng, k: usize, specular: f32) -> Path {
    let cam = Camera::new(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, Vec3::Y, 60.0, 64, 48).unwrap();
    let mut x: Vec<Vec3> = (0..k).map(|_| rng.v()).collect();
    x.push(cam.eye);
    let mut sp = Vec::new();
    let mut bsdf = Vec::new();
    for i in 0..k {
        let to_next = (x[i + 1] - x[i]).normalize();
        let n = if i == 0 {
            (to_next + 0.5 * rng.v()).normalize()
        } else {
            ((x[i - 1] - x[i]).normalize() + to_next + 0.6 * rng.v()).normalize()
        };
        // Both neighbours on the normal's side (reflection); light faces x1.
        let ok = to_next.dot(n) > 0.05 && (i == 0 || (x[i - 1] - x[i]).normalize().dot(n) > 0.05);
        let n = if ok { n } else { (to_next + if i == 0 { Vec3::ZERO } else { (x[i - 1] - x[i]).normalize() }).normalize() };
        sp.push(ShadingPoint::new(n, n));
        bsdf.push(if rng.f() < 0.5 {
            Bsdf::Lambertian(Lambertian { albedo: Color::splat(0.7) })
        } else {
            Bsdf::Glossy(Glossy { kd: Color::splat(0.3), ks: Color::splat(0.5), exponent: 5.0 + 40.0 * rng.f() })
        });
    }
    let delta = (0..k).map(|i| i > 0 && specular > 0.0 && rng.f() < specular).collect();
    Path { x, sp, bsdf, delta, cam, area: 0.2 + rng.f(), pick: 0.3 + 0.7 * rng.f() }
}

impl Path {
    fn k(&self) -> usize {
        self.x.len() - 1
    }
    fn dir(&self, from: usize, to: usize) -> Vec3 {
        (self.x[to] - self.x[from]).normalize()
    }
    fn d2(&self, a: usize, b: usize) -> f32 {
        self.x[a].distance_squared(self.x[b])
    }
    /// |cos| at vertex i towards vertex j (geometric normal).
    fn cos(&self, i: usize, j: usize) -> f32 {
        self.dir(i, j).dot(self.sp[i].ng).abs()
    }
    /// BSDF density at i of sampling the direction to `to` given the one to `from`.
    /// (The delta factor of a delta vertex is 1.)
    fn pdf(&self, i: usize, from: usize, to: usize) -> f32 {
        if self.delta[i] { 1.0 } else { self.bsdf[i].pdf(&self.sp[i], self.dir(i, from), self.dir(i, to)) }
    }
    /// Whether merging at x_j exists (`first`: only at the last non-delta vertex).
    fn merges_at(&self, j: usize, first: bool) -> bool {
        !self.delta[j] && (!first || (j + 1..self.k()).all(|i| self.delta[i]))
    }
    fn emission_pdf_w(&self) -> f32 {
        self.pick / self.area * self.cos(0, 1) / PI
    }
    /// Area density of x_i sampled from the light side.
    fn pl(&self, i: usize) -> f32 {
        match i {
            0 => self.pick / self.area,
            1 => self.cos(0, 1) / PI * self.cos(1, 0) / self.d2(0, 1),
            _ => self.pdf(i - 1, i - 2, i) * self.cos(i, i - 1) / self.d2(i - 1, i),
        }
    }
    /// Area density of x_i sampled from the camera side (i ≤ k − 1).
    fn pc(&self, i: usize) -> f32 {
        let k = self.k();
        if i == k - 1 {
            self.cam.pdf_dir(self.x[i] - self.cam.eye) * self.cos(i, k) / self.d2(i, k)
        } else {
            self.pdf(i + 1, i + 2, i) * self.cos(i, i + 1) / self.d2(i, i + 1)
        }
    }
}

/// Brute force: every technique's effective density (sample counts included; 0 where
/// the technique does not exist), in the order s = 0 … k, then merges at j = 1 … k − 1.
/// Inner connections (2 ≤ s ≤ k − 1) count `conn` samples, light tracing `n_light`,
/// emitter hits and direct sampling 1.
fn brute(p: &Path, merge: bool, first: bool, eta: f32, n_light: f32, conn: f32) -> Vec<f32> {
    let k = p.k();
    let mut raw = Vec::new();
    for s in 0..=k {
        let mut v = 1.0;
        for i in 0..s {
            v *= p.pl(i);
        }
        for j in s..k {
            v *= p.pc(j);
        }
        raw.push(v);
    }
    let mut q: Vec<f32> = (0..=k)
        .map(|s| {
            // Connections (s ≥ 1) join x_{s−1} and x_s (the eye for s = k).
            if s >= 1 && (p.delta[s - 1] || (s < k && p.delta[s])) {
                return 0.0;
            }
            raw[s]
                * if s == k {
                    n_light
                } else if s >= 2 {
                    conn
                } else {
                    1.0
                }
        })
        .collect();
    if merge {
        q.extend((1..k).map(|j| if p.merges_at(j, first) { eta * raw[j] * p.pl(j) } else { 0.0 }));
    }
    q
}

/// Light partials at x_i (arrived).
fn light_partials(p: &Path, f: &Factors, i: usize) -> Partials {
    let mut l = Partials::light_start(f, p.pick / p.area, p.emission_pdf_w(), p.cos(0, 1), false, true);
    for v in 1..=i {
        if v > 1 {
            l.scatter(f, p.cos(v - 1, v), p.pdf(v - 1, v - 2, v), p.pdf(v - 1, v, v - 2), p.delta[v - 1]);
        }
        l.arrive(f.h, Some(p.d2(v - 1, v)), p.cos(v, v - 1));
    }
    l
}

/// Camera partials at x_j (arrived).
fn camera_partials(p: &Path, f: &Factors, j: usize) -> Partials {
    let k = p.k();
    let mut c = Partials::camera_start(f, p.cam.pdf_dir(p.x[k - 1] - p.cam.eye));
    for v in (j..k).rev() {
        if v < k - 1 {
            c.scatter(f, p.cos(v + 1, v), p.pdf(v + 1, v + 2, v), p.pdf(v + 1, v, v + 2), p.delta[v + 1]);
        }
        c.arrive(f.h, Some(p.d2(v + 1, v)), p.cos(v, v + 1));
    }
    c
}

/// The weights from the partials, same order as [`brute`].
fn recursive(p: &Path, f: &Factors, merge: bool, plant: bool) -> Vec<f32> {
    // Merging exists at non-delta vertices where the partials say so (`vcm_merge =
    // "first"`: at the last non-delta vertex); techniques that do not exist weigh 0.
    let k = p.k();
    let mut w = Vec::new();
    let c0 = camera_partials(p, f, 0);
    w.push(weight_hit(f, &c0, p.pick / p.area, p.emission_pdf_w()));
    let c1 = camera_partials(p, f, 1);
    let direct_pdf_w = p.d2(0, 1) / (p.cos(0, 1) * p.area);
    let emission_pdf_w = p.cos(0, 1) / (PI * p.area);
    let cam_next = 2;
    w.push(if p.delta[1] {
        0.0
    } else {
        weight_direct(
            f,
            &c1,
            p.pick,
            direct_pdf_w,
            emission_pdf_w,
            p.cos(0, 1),
            false,
            p.pdf(1, cam_next, 0),
            p.pdf(1, 0, cam_next),
            p.cos(1, 0),
        )
    });
    for s in 2..k {
        if p.delta[s - 1] || p.delta[s] {
            w.push(0.0);
            continue;
        }
        let (l, c) = (light_partials(p, f, s - 1), camera_partials(p, f, s));
        let d2 = p.d2(s - 1, s);
        let cam_to_light_a = w_to_a(p.pdf(s, s + 1, s - 1), d2, p.cos(s - 1, s));
        let light_to_cam_a = w_to_a(p.pdf(s - 1, s - 2, s), d2, p.cos(s, s - 1));
        let (mut light_rev, mut cam_rev) = (p.pdf(s - 1, s, s - 2), p.pdf(s, s - 1, s + 1));
        if plant {
            std::mem::swap(&mut light_rev, &mut cam_rev);
        }
        w.push(weight_connect(f, &l, &c, cam_to_light_a, light_to_cam_a, light_rev, cam_rev));
    }
    let l = light_partials(p, f, k - 1);
    let camera_pdf_a = p.cam.pdf_dir(p.x[k - 1] - p.cam.eye) * p.cos(k - 1, k) / p.d2(k - 1, k);
    w.push(if p.delta[k - 1] { 0.0 } else { weight_camera(f, &l, camera_pdf_a, p.pdf(k - 1, k, k - 2)) });
    if merge {
        for j in 1..k {
            let (l, c) = (light_partials(p, f, j), camera_partials(p, f, j));
            w.push(if c.merges && !p.delta[j] { weight_merge(f, &l, &c, p.pdf(j, j + 1, j - 1), p.pdf(j, j - 1, j + 1)) } else { 0.0 });
        }
    }
    w
}

/// Over many random paths of 3–7 edges: (largest |weight − brute force|, largest
/// |Σ weights − 1|, share of paths whose sum is off by more than 1 %).
/// `n_light` light subpaths per pass, inner connections counting `conn` (1: each camera
/// vertex joined to its own light subpath).
/// `first`: merging at the first non-delta camera vertex only.
/// `specular`: share of delta inner vertices.
fn check(h: Heuristic, merge: bool, first: bool, plant: bool, n_light: f32, conn: f32, specular: f32) -> (f32, f32, f32) {
    let mut rng = Rng(0xB1D1 + merge as u64);
    let r = 0.01;
    let f = Factors::new(h, true, merge, !first, r, n_light, conn);
    let eta = PI * r * r * n_light;
    let (mut worst_w, mut worst_sum, mut off) = (0.0f32, 0.0f32, 0usize);
    let trials = 2000;
    for t in 0..trials {
        let p = random_path(&mut rng, 3 + t % 5, specular);
        let q = brute(&p, merge, first, eta, n_light, conn);
        let qb: Vec<f64> = q.iter().map(|&v| (h.mis(1.0) as f64) * (v as f64).powi(if h == Heuristic::Power { 2 } else { 1 })).collect();
        let total: f64 = qb.iter().sum();
        let w = recursive(&p, &f, merge, plant);
        assert_eq!(w.len(), q.len());
        for (wi, qi) in w.iter().zip(&qb) {
            worst_w = worst_w.max((*wi as f64 - qi / total).abs() as f32);
        }
        let sum: f32 = w.iter().sum();
        worst_sum = worst_sum.max((sum - 1.0).abs());
        off += ((sum - 1.0).abs() > 0.01) as usize;
    }
    (worst_w, worst_sum, off as f32 / trials as f32)
}

/// (light subpaths per pass, inner-connection count): one per pixel and own light
/// subpath (SmallVCM); a quarter of the pixels; a quarter with one vertex drawn from
/// the pool of ~2.5 vertices per subpath; twice the pixels with three drawn.
const COUNTS: [(f32, f32); 4] = [(64.0 * 48.0, 1.0), (64.0 * 12.0, 1.0), (64.0 * 12.0, 0.4), (64.0 * 96.0, 1.2)];

#[test]
fn recursive_weights_equal_the_heuristic_and_sum_to_one() {
    for h in [Heuristic::Balance, Heuristic::Power] {
        for (merge, first) in [(false, false), (true, false), (true, true)] {
            for (n_light, conn) in COUNTS {
                for specular in [0.0, 0.35] {
                    let (w, s, _) = check(h, merge, first, false, n_light, conn, specular);
                    assert!(
                        w < 2e-3 && s < 2e-3,
                        "{h:?} merge {merge} (first only: {first}) {n_light} light paths, connections ×{conn}, \
                         specular share {specular}: worst weight error {w}, worst sum error {s}"
                    );
                }
            }
        }
    }
}

#[test]
fn planted_wrong_reverse_density_breaks_the_sum() {
    for h in [Heuristic::Balance, Heuristic::Power] {
        for first in [false, true] {
            for (n_light, conn) in COUNTS {
                let (_, s, off) = check(h, true, first, true, n_light, conn, 0.0);
                assert!(
                    s > 0.1 && off > 0.3,
                    "{h:?}, first only {first}, connections ×{conn}: planted bug not caught (worst sum error {s}, {off} of paths off)"
                );
            }
        }
    }
}

/// The unidirectional share w₀ + w₁ (`uni_*` of [`super::mis`]) of each technique's
/// sample, same order as [`recursive`] (`plant`: dVC's share left out of a connection's).
fn recursive_uni(p: &Path, f: &Factors, merge: bool, plant: bool) -> Vec<f32> {
    let k = p.k();
    let w = recursive(p, f, merge, false);
    let mut r = Vec::new();
    r.push(uni_hit(f, &camera_partials(p, f, 0), p.pick / p.area));
    let direct_pdf_w = p.d2(0, 1) / (p.cos(0, 1) * p.area);
    r.push(uni_direct(f, p.pick, direct_pdf_w, false, p.pdf(1, 2, 0)));
    for s in 2..k {
        let l = light_partials(p, f, s - 1);
        let cam_to_light_a = w_to_a(p.pdf(s, s + 1, s - 1), p.d2(s - 1, s), p.cos(s - 1, s));
        let rev = if plant { 0.0 } else { p.pdf(s - 1, s, s - 2) };
        r.push(uni_connect(f, &l, cam_to_light_a, rev));
    }
    let l = light_partials(p, f, k - 1);
    let camera_pdf_a = p.cam.pdf_dir(p.x[k - 1] - p.cam.eye) * p.cos(k - 1, k) / p.d2(k - 1, k);
    r.push(uni_camera(f, &l, camera_pdf_a, p.pdf(k - 1, k, k - 2)));
    if merge {
        for j in 1..k {
            r.push(uni_merge(f, &light_partials(p, f, j), p.pdf(j, j + 1, j - 1)));
        }
    }
    w.iter().zip(&r).map(|(&w, &r)| uni_share(w, r)).collect()
}

/// Largest |unidirectional share − (p₀ + p₁)/Σ p| over the techniques that can sample
/// random paths (balance heuristic).
fn check_uni(merge: bool, first: bool, plant: bool, n_light: f32, conn: f32, specular: f32) -> f32 {
    let mut rng = Rng(0x0E1 + merge as u64);
    let r = 0.01;
    let f = Factors::new(Heuristic::Balance, true, merge, !first, r, n_light, conn);
    let eta = PI * r * r * n_light;
    let mut worst = 0.0f32;
    for t in 0..2000 {
        let p = random_path(&mut rng, 3 + t % 5, specular);
        let q = brute(&p, merge, first, eta, n_light, conn);
        let total: f64 = q.iter().map(|&v| v as f64).sum();
        let want = ((q[0] as f64 + q[1] as f64) / total) as f32;
        let w = recursive(&p, &f, merge, false);
        for (wi, ui) in w.iter().zip(recursive_uni(&p, &f, merge, plant)) {
            if *wi > 1e-4 {
                worst = worst.max((ui - want).abs() / want.max(1e-3));
            }
        }
    }
    worst
}

#[test]
fn unidirectional_share_equals_the_heuristics() {
    for (merge, first) in [(false, false), (true, false), (true, true)] {
        for (n_light, conn) in COUNTS {
            for specular in [0.0, 0.35] {
                let e = check_uni(merge, first, false, n_light, conn, specular);
                assert!(e < 5e-3, "merge {merge} (first {first}), {n_light} light paths, ×{conn}, specular {specular}: relative error {e}");
            }
        }
    }
    // Planted: a connection's share without dVC's part (the emitter hit's term).
    let e = check_uni(true, true, true, COUNTS[0].0, COUNTS[0].1, 0.0);
    assert!(e > 0.1, "planted error not caught: {e}");
}
