//! Multiple importance sampling of bidirectional techniques in constant time per
//! connection: the recursive partial weights dVCM, dVC, dVM of Georgiev, Křivánek,
//! Davidovič & Slusallek, "Light transport simulation with vertex connection and
//! merging" (SIGGRAPH Asia 2012) and its technical report (§4, eqs. 31–55), in the
//! formulation of SmallVCM.
//!
//! Each subpath carries three numbers updated once per vertex; the weight of a
//! technique that joins a light subpath ending at y and a camera subpath ending at z
//! is 1 / (w_light + 1 + w_camera), where each side's sum over the techniques that
//! would have sampled more of the path from the *other* end comes out of its partials
//! and the two densities of the joining step. All densities here are without Russian
//! roulette: roulette only rescales a technique's own estimate by 1/q, so any weights
//! computed from the path alone keep the combination unbiased (pbrt's BDPT leaves it
//! out too; SmallVCM folds its albedo-based roulette in, which this crate's
//! throughput-based policies would not allow). Cosines are taken with geometric
//! normals, the area densities' true conversion factors.

/// The heuristic: balance (exponent 1) or power (exponent 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heuristic {
    /// w_i = p_i / Σ p_j.
    Balance,
    /// w_i = p_i² / Σ p_j² (Veach's power heuristic, β = 2).
    Power,
}

impl Heuristic {
    /// Names accepted by `bdpt_mis`.
    pub const NAMES: &'static [&'static str] = &["balance", "power"];

    /// Parses `balance` / `power`.
    pub fn parse(s: &str) -> anyhow::Result<Self> {
        match s {
            "balance" => Ok(Heuristic::Balance),
            "power" => Ok(Heuristic::Power),
            _ => anyhow::bail!("unknown bdpt_mis `{s}` (known: {})", Self::NAMES.join(", ")),
        }
    }

    /// x^β.
    #[inline]
    pub fn mis(self, x: f32) -> f32 {
        match self {
            Heuristic::Balance => x,
            Heuristic::Power => x * x,
        }
    }
}

/// Per-pass constants: which techniques are on and their relative sample counts.
///
/// Sample counts per camera subpath: emitter hits (s = 0) and direct light sampling
/// (s = 1) 1 each, inner connections (s ≥ 2, t ≥ 2) `conn_count` (1 when every camera
/// vertex is joined to its own light subpath; M / L̄ when it is joined to M vertices
/// drawn from the pass's pool, L̄ light vertices per light subpath), light tracing
/// `light_paths`, merging π r² · `light_paths`. The partials are kept in units where an
/// inner connection counts 1, so with `conn_count` = 1 they are SmallVCM's.
#[derive(Clone, Copy, Debug)]
pub struct Factors {
    /// The heuristic.
    pub h: Heuristic,
    /// mis(η) with η = π r² · light paths / `conn_count`, 0 without merging.
    pub vm_weight: f32,
    /// mis(1/η), 0 without connections.
    pub vc_weight: f32,
    /// Light subpaths per pass (the light-tracing technique's sample count).
    pub light_paths: f32,
    /// light_paths / `conn_count`: the light-tracing count relative to a connection's.
    pub lt_count: f32,
    /// mis(`conn_count`).
    pub conn: f32,
    /// Merging at every non-delta camera vertex (`vcm_merge = "all"`); false: only at
    /// the first one (`"first"`, see [`Partials::merges`]).
    pub merge_all: bool,
}

impl Factors {
    /// Factors for merging radius `r` (ignored unless `merge`), `light_paths` light
    /// subpaths per pass and inner connections counting `conn_count` per camera vertex;
    /// merging at every non-delta camera vertex (`merge_all`) or at the first only.
    pub fn new(h: Heuristic, connect: bool, merge: bool, merge_all: bool, r: f32, light_paths: f32, conn_count: f32) -> Self {
        let eta = std::f32::consts::PI * r * r * light_paths / conn_count;
        Factors {
            h,
            vm_weight: if merge { h.mis(eta) } else { 0.0 },
            vc_weight: if connect && merge { h.mis(1.0 / eta) } else { 0.0 },
            light_paths,
            lt_count: light_paths / conn_count,
            conn: h.mis(conn_count),
            merge_all,
        }
    }
}

/// The partial weights of a subpath at its last vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Partials {
    /// dVCM: techniques that differ in the last vertex's sampling.
    pub dvcm: f32,
    /// dVC: connection techniques further along.
    pub dvc: f32,
    /// dVM: merging techniques further along.
    pub dvm: f32,
    /// Whether the merging technique exists at the current vertex (when it is
    /// non-delta and, on a light subpath, a non-delta camera vertex lies beyond it).
    /// Always with `vcm_merge = "all"`; with `"first"` only on a camera subpath whose
    /// earlier vertices are all delta (see [`Partials::scatter`]).
    pub merges: bool,
    /// The part of dVC that stands for the unidirectional techniques (s = 0 and s = 1:
    /// path tracing's), on a light subpath; 0 on a camera subpath.
    pub duc: f32,
    /// The part of dVCM that stands for them (until the light subpath's first scattering).
    pub dum: f32,
}

impl Partials {
    /// A light subpath leaving its emitter (tech. report eqs. 31–33 before the
    /// first hit): densities as [`super::lights::Emission`].
    pub fn light_start(f: &Factors, direct_pdf_a: f32, emission_pdf_w: f32, cos: f32, delta: bool, finite: bool) -> Self {
        // Both terms stand for techniques counted 1 (s = 1 and s = 0), not `conn_count`.
        let dvcm = f.h.mis(direct_pdf_a / emission_pdf_w) / f.conn;
        let dvc = if delta { 0.0 } else { f.h.mis(if finite { cos } else { 1.0 } / emission_pdf_w) / f.conn };
        Partials { dvcm, dvc, dvm: dvc * f.vc_weight, merges: f.merge_all, duc: dvc, dum: dvcm }
    }

    /// A camera subpath leaving the eye with direction density `camera_pdf_w`.
    pub fn camera_start(f: &Factors, camera_pdf_w: f32) -> Self {
        Partials { dvcm: f.h.mis(f.lt_count / camera_pdf_w), dvc: 0.0, dvm: 0.0, merges: true, duc: 0.0, dum: 0.0 }
    }

    /// Completes the update on arriving at a vertex at squared distance `dist2`
    /// (`None`: the first hit of a ray from a light at infinity) with geometric cosine
    /// `cos` there.
    #[inline]
    pub fn arrive(&mut self, h: Heuristic, dist2: Option<f32>, cos: f32) {
        if let Some(d2) = dist2 {
            self.dvcm *= h.mis(d2);
        }
        let c = h.mis(cos.abs());
        self.dvcm /= c;
        self.dvc /= c;
        self.dvm /= c;
        if let Some(d2) = dist2 {
            self.dum *= h.mis(d2);
        }
        self.dum /= c;
        self.duc /= c;
    }

    /// Update for scattering from the last vertex (eqs. 34–36; specular 53–55): the
    /// sampled direction's density `pdf_dir`, the reverse density `pdf_rev`, geometric
    /// cosine `cos_out` of the new direction. A delta lobe's `pdf_dir` = `pdf_rev`.
    ///
    /// The terms of merging at the scattering vertex (`vm_weight` in dVC, 1 in dVM)
    /// enter only where that technique exists ([`Partials::merges`]). With merging at
    /// the first non-delta camera vertex only (`vcm_merge = "first"`), a full path
    /// x₀ … x_k (x_k the eye) has one merging technique, at the first non-delta vertex
    /// seen from the eye, x_f (x_{f+1} … x_{k−1} delta). A light subpath's partials at
    /// y_s serve techniques whose camera side starts with a non-delta vertex (the
    /// connections; light tracing adds its own merge at y_s in [`weight_camera`]),
    /// so no merging at y_j, j ≤ s, lies on their paths: the light subpath carries no
    /// merging terms. A camera subpath adds the merge at its first non-delta vertex
    /// when it scatters there, then none: `merges` becomes `merge_all` after the
    /// first non-delta scattering (a delta one keeps it). Since dVM = vc_weight · dVC
    /// holds through the recursion (vm_weight · vc_weight = 1), the merge terms drop
    /// from both alike.
    #[inline]
    pub fn scatter(&mut self, f: &Factors, cos_out: f32, pdf_dir: f32, pdf_rev: f32, specular: bool) {
        let h = f.h;
        if specular {
            self.dvcm = 0.0;
            self.dvc *= h.mis(cos_out.abs());
            self.dvm *= h.mis(cos_out.abs());
            self.dum = 0.0;
            self.duc *= h.mis(cos_out.abs());
        } else {
            let g = h.mis(cos_out.abs() / pdf_dir);
            let (dvcm, dvc, dvm) = (self.dvcm, self.dvc, self.dvm);
            let (vm, one) = if self.merges { (f.vm_weight, 1.0) } else { (0.0, 0.0) };
            self.dvc = g * (dvc * h.mis(pdf_rev) + dvcm + vm);
            self.dvm = g * (dvm * h.mis(pdf_rev) + dvcm * f.vc_weight + one);
            self.dvcm = h.mis(1.0 / pdf_dir);
            self.merges = f.merge_all;
            self.duc = g * (self.duc * h.mis(pdf_rev) + self.dum);
            self.dum = 0.0;
        }
    }

    /// `vm_weight` where merging exists at the current vertex, else 0.
    #[inline]
    fn vm(&self, f: &Factors) -> f32 {
        if self.merges { f.vm_weight } else { 0.0 }
    }
}

/// Weight of a camera path hitting an emitter (s = 0, eq. 43); `direct_pdf_a` and
/// `emission_pdf_w` from [`super::lights::emitter_pdfs`].
#[inline]
pub fn weight_hit(f: &Factors, cam: &Partials, direct_pdf_a: f32, emission_pdf_w: f32) -> f32 {
    // dvcm stands for direct sampling (counted as this technique), dvc for techniques
    // in connection units.
    let w_camera = f.h.mis(direct_pdf_a) * cam.dvcm + f.conn * f.h.mis(emission_pdf_w) * cam.dvc;
    1.0 / (1.0 + w_camera)
}

/// Weight of direct sampling (s = 1, eqs. 44–45): `bsdf_dir` / `bsdf_rev` the camera
/// vertex's densities towards / from the light, `cos_geo` the geometric cosine there.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn weight_direct(
    f: &Factors,
    cam: &Partials,
    pick: f32,
    direct_pdf_w: f32,
    emission_pdf_w: f32,
    cos_at_light: f32,
    delta: bool,
    bsdf_dir: f32,
    bsdf_rev: f32,
    cos_geo: f32,
) -> f32 {
    let h = f.h;
    let w_light = if delta { 0.0 } else { h.mis(bsdf_dir / (pick * direct_pdf_w)) };
    // The camera side's techniques are in connection units; this one counts 1.
    let w_camera =
        f.conn * h.mis(emission_pdf_w * cos_geo.abs() / (direct_pdf_w * cos_at_light)) * (cam.vm(f) + cam.dvcm + cam.dvc * h.mis(bsdf_rev));
    1.0 / (w_light + 1.0 + w_camera)
}

/// Weight of light tracing (t = 1, eq. 46): `camera_pdf_a` is the area density of the
/// light vertex under camera sampling, `bsdf_rev` the light vertex's density towards
/// its predecessor given the eye direction. The light vertex is the first camera
/// vertex of this path, so merging exists there in either `vcm_merge` mode.
#[inline]
pub fn weight_camera(f: &Factors, light: &Partials, camera_pdf_a: f32, bsdf_rev: f32) -> f32 {
    let w_light = f.h.mis(camera_pdf_a / f.lt_count) * (f.vm_weight + light.dvcm + light.dvc * f.h.mis(bsdf_rev));
    1.0 / (w_light + 1.0)
}

/// Weight of connecting two inner vertices (eqs. 40–41): each side's area density of
/// sampling the other vertex (`cam_to_light_a`: the camera vertex's BSDF sampling the
/// light vertex) and its reverse solid-angle density.
#[inline]
pub fn weight_connect(
    f: &Factors,
    light: &Partials,
    cam: &Partials,
    cam_to_light_a: f32,
    light_to_cam_a: f32,
    light_rev: f32,
    cam_rev: f32,
) -> f32 {
    let h = f.h;
    let w_light = h.mis(cam_to_light_a) * (light.vm(f) + light.dvcm + light.dvc * h.mis(light_rev));
    let w_camera = h.mis(light_to_cam_a) * (cam.vm(f) + cam.dvcm + cam.dvc * h.mis(cam_rev));
    1.0 / (w_light + 1.0 + w_camera)
}

/// Weight of merging a light vertex at a camera vertex (eqs. 37–39): `cam_dir` is the
/// camera vertex's density of sampling the light vertex's incoming direction,
/// `cam_rev` the reverse.
#[inline]
pub fn weight_merge(f: &Factors, light: &Partials, cam: &Partials, cam_dir: f32, cam_rev: f32) -> f32 {
    let w_light = light.dvcm * f.vc_weight + light.dvm * f.h.mis(cam_dir);
    let w_camera = cam.dvcm * f.vc_weight + cam.dvm * f.h.mis(cam_rev);
    1.0 / (w_light + 1.0 + w_camera)
}

/// The unidirectional techniques' share of the weights, w₀ + w₁ (s = 0 and s = 1, what
/// path tracing samples), of a path that technique t sampled with weight `w`, from
/// `ratio` = Σ over those techniques of mis(p_s) / mis(p_t) (the `uni_*` functions):
/// exact under the balance heuristic; under the power one the same sums of squares.
#[inline]
pub fn uni_share(w: f32, ratio: f32) -> f32 {
    (w * ratio).clamp(0.0, 1.0)
}

/// [`uni_share`]'s ratio for a camera path hitting an emitter (s = 0; arguments as
/// [`weight_hit`]): itself and direct sampling.
#[inline]
pub fn uni_hit(f: &Factors, cam: &Partials, direct_pdf_a: f32) -> f32 {
    1.0 + f.h.mis(direct_pdf_a) * cam.dvcm
}

/// [`uni_share`]'s ratio for direct sampling (s = 1; arguments as [`weight_direct`]):
/// itself and the emitter hit.
#[inline]
pub fn uni_direct(f: &Factors, pick: f32, direct_pdf_w: f32, delta: bool, bsdf_dir: f32) -> f32 {
    1.0 + if delta { 0.0 } else { f.h.mis(bsdf_dir / (pick * direct_pdf_w)) }
}

/// [`uni_share`]'s ratio for an inner connection (arguments as [`weight_connect`]).
#[inline]
pub fn uni_connect(f: &Factors, light: &Partials, cam_to_light_a: f32, light_rev: f32) -> f32 {
    f.h.mis(cam_to_light_a) * (light.dum + light.duc * f.h.mis(light_rev))
}

/// [`uni_share`]'s ratio for light tracing (arguments as [`weight_camera`]).
#[inline]
pub fn uni_camera(f: &Factors, light: &Partials, camera_pdf_a: f32, bsdf_rev: f32) -> f32 {
    f.h.mis(camera_pdf_a / f.lt_count) * (light.dum + light.duc * f.h.mis(bsdf_rev))
}

/// [`uni_share`]'s ratio for merging (arguments as [`weight_merge`]; dVM's share of
/// the unidirectional techniques is vc_weight times dVC's).
#[inline]
pub fn uni_merge(f: &Factors, light: &Partials, cam_dir: f32) -> f32 {
    f.vc_weight * (light.dum + light.duc * f.h.mis(cam_dir))
}

/// Converts a solid-angle density at one vertex into an area density at the other
/// (distance² `dist2`, geometric cosine `cos_there` at the receiving vertex).
#[inline]
pub fn w_to_a(pdf_w: f32, dist2: f32, cos_there: f32) -> f32 {
    pdf_w * cos_there.abs() / dist2
}
