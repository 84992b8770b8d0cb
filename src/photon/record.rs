//! Compact photon record: 8 bytes of payload; the kd-tree keeps each photon's
//! position (8 bytes, quantised, with its split axis), so a stored photon takes
//! 16 bytes in all.
//!
//! | bytes | field |
//! |---|---|
//! | 4 | power, RGBE shared exponent (Ward), ~0.4 % precision of the largest channel |
//! | 2 | incoming direction, octahedral 8 + 8 bits |
//! | 2 | surface normal, octahedral 8 + 8 bits |

use crate::math::Color;
use glam::{Vec2, Vec3};

/// One stored photon.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Photon {
    rgbe: [u8; 4],
    dir: u16,
    normal: u16,
}

const _: () = assert!(std::mem::size_of::<Photon>() == 8);

/// Shared-exponent RGB encoding (Ward's RGBE).
pub fn encode_rgbe(c: Color) -> [u8; 4] {
    let m = c.max_element();
    if m.is_nan() || m <= 1e-32 || m.is_infinite() {
        return [0; 4];
    }
    let (_, e) = frexp(m);
    let scale = 256.0 / exp2i(e);
    let q = |v: f32| (v.max(0.0) * scale).min(255.0) as u8;
    [q(c.x), q(c.y), q(c.z), (e + 128).clamp(0, 255) as u8]
}

/// Decodes [`encode_rgbe`] (at the centre of each quantisation step).
pub fn decode_rgbe(v: [u8; 4]) -> Color {
    if v[3] == 0 {
        return Color::ZERO;
    }
    let f = exp2i(v[3] as i32 - 128 - 8);
    let d = |b: u8| if b == 0 { 0.0 } else { (b as f32 + 0.5) * f };
    Color::new(d(v[0]), d(v[1]), d(v[2]))
}

/// 2^e for e in [−252, 254] (clamped), exactly (rounded like any product where it
/// falls below the normal range): two factors built from exponent bits. `powi` is
/// a library call, which the compiler may also hoist out of a branch, and this sits
/// in the radiance estimate's per-photon loop.
#[inline]
fn exp2i(e: i32) -> f32 {
    let e = e.clamp(-252, 254);
    let h = e / 2;
    let bits = |x: i32| f32::from_bits(((x + 127) as u32) << 23);
    bits(h) * bits(e - h)
}

/// Mantissa in [0.5, 1) and exponent with x = m·2^e.
fn frexp(x: f32) -> (f32, i32) {
    let e = x.log2().floor() as i32 + 1;
    let mut m = x / exp2i(e);
    let mut e = e;
    // Guard rounding of log2 near powers of two.
    if m >= 1.0 {
        m /= 2.0;
        e += 1;
    } else if m < 0.5 {
        m *= 2.0;
        e -= 1;
    }
    (m, e)
}

/// Octahedral map of a unit vector to [-1, 1]².
fn oct_encode(n: Vec3) -> Vec2 {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs()).max(1e-20);
    if n.z >= 0.0 { Vec2::new(n.x, n.y) } else { Vec2::new((1.0 - n.y.abs()) * n.x.signum(), (1.0 - n.x.abs()) * n.y.signum()) }
}

fn oct_decode(e: Vec2) -> Vec3 {
    oct_unfold(e).normalize_or_zero()
}

/// The octahedron's point for `e` (|x| + |y| + |z| = 1): the direction, unnormalised.
fn oct_unfold(e: Vec2) -> Vec3 {
    let z = 1.0 - e.x.abs() - e.y.abs();
    let (x, y) = if z >= 0.0 { (e.x, e.y) } else { ((1.0 - e.y.abs()) * e.x.signum(), (1.0 - e.x.abs()) * e.y.signum()) };
    Vec3::new(x, y, z)
}

fn quant(v: f32, bits: u32) -> u16 {
    let max = ((1u32 << bits) - 1) as f32;
    ((v.clamp(-1.0, 1.0) * 0.5 + 0.5) * max).round() as u16
}

#[cfg(test)]
fn dequant(q: u16, bits: u32) -> f32 {
    let max = ((1u32 << bits) - 1) as f32;
    q as f32 / max * 2.0 - 1.0
}

/// [`dequant`] of every 8-bit code, as a table: the estimates decode a direction per
/// photon, and the division is most of the decode's cost.
static DEQUANT8: [f32; 256] = {
    let mut t = [0.0f32; 256];
    let mut q = 0;
    while q < 256 {
        t[q] = q as f32 / 255.0 * 2.0 - 1.0;
        q += 1;
    }
    t
};

/// The two 8-bit components of an octahedral code.
#[inline(always)]
fn oct_code(c: u16) -> Vec2 {
    Vec2::new(DEQUANT8[(c & 0xFF) as usize], DEQUANT8[(c >> 8) as usize])
}

/// One decoded octahedral code, padded to 16 bytes so that four load into an SSE
/// register each.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct DecodedDir(pub [f32; 4]);

/// Every 16-bit octahedral code decoded ([`oct_decode`] of [`oct_code`]; 1 MiB,
/// built on first use): directions and normals are read tens of millions of times
/// per render, and a lookup returns exactly the bits the decode computes.
pub fn dir_table() -> &'static [DecodedDir] {
    static TABLE: std::sync::LazyLock<Vec<DecodedDir>> = std::sync::LazyLock::new(|| {
        (0..=u16::MAX)
            .map(|c| {
                let v = oct_decode(oct_code(c));
                DecodedDir([v.x, v.y, v.z, 0.0])
            })
            .collect()
    });
    &TABLE
}

/// The direction of a 16-bit octahedral code, from [`dir_table`].
#[inline(always)]
pub fn decode_dir(code: u16) -> Vec3 {
    let [x, y, z, _] = dir_table()[code as usize].0;
    Vec3::new(x, y, z)
}

/// The 16-bit octahedral code (8 + 8 bits) of a unit vector.
#[inline]
pub fn encode_dir(v: Vec3) -> u16 {
    let e = oct_encode(v);
    quant(e.x, 8) | (quant(e.y, 8) << 8)
}

impl Photon {
    /// Packs a photon (its position goes to the kd-tree). `dir` points back towards
    /// where the photon came from; `normal` is the surface normal on the side the
    /// photon arrived from.
    pub fn new(power: Color, dir: Vec3, normal: Vec3) -> Self {
        Self::from_codes(power, encode_dir(dir), encode_dir(normal))
    }
    /// Packs a photon whose direction and normal are already encoded ([`encode_dir`]).
    #[inline]
    pub fn from_codes(power: Color, dir: u16, normal: u16) -> Self {
        Photon { rgbe: encode_rgbe(power), dir, normal }
    }
    /// Power (flux).
    #[inline]
    pub fn power(&self) -> Color {
        decode_rgbe(self.rgbe)
    }
    /// Replaces the power.
    pub fn set_power(&mut self, c: Color) {
        self.rgbe = encode_rgbe(c);
    }
    /// Unit incoming direction (towards the photon's origin).
    #[inline]
    pub fn direction(&self) -> Vec3 {
        decode_dir(self.dir)
    }
    /// [`Photon::direction`] before normalisation (a positive multiple of it), for
    /// tests that need only signs.
    #[inline]
    pub fn direction_unnormalised(&self) -> Vec3 {
        oct_unfold(oct_code(self.dir))
    }
    /// Unit surface normal on the side the photon arrived from.
    #[inline]
    pub fn normal(&self) -> Vec3 {
        decode_dir(self.normal)
    }
    /// The normal's code ([`encode_dir`]).
    #[inline]
    pub fn normal_code(&self) -> u16 {
        self.normal
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dequant_table_is_dequant() {
        for q in 0..=u16::MAX {
            assert_eq!(oct_code(q), Vec2::new(dequant(q & 0xFF, 8), dequant(q >> 8, 8)));
        }
    }

    #[test]
    fn dir_table_is_the_decode() {
        for c in 0..=u16::MAX {
            let want = oct_decode(oct_code(c));
            assert_eq!(decode_dir(c).to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "code {c}");
        }
        let v = Vec3::new(0.3, -0.8, 0.2).normalize();
        assert_eq!(encode_dir(v), Photon::new(Color::ONE, v, v).normal_code());
    }

    #[test]
    fn exp2i_is_powi() {
        for e in -126..=127 {
            assert_eq!(exp2i(e).to_bits(), 2f32.powi(e).to_bits(), "2^{e}");
        }
        // Below the normal range: the exact subnormal, then zero; above: infinity.
        for e in -149..-126 {
            assert_eq!(exp2i(e).to_bits(), 1 << (e + 149), "2^{e}");
        }
        assert_eq!((exp2i(-150), exp2i(-400), exp2i(128), exp2i(400)), (0.0, 0.0, f32::INFINITY, f32::INFINITY));
    }
    use crate::math::uniform_sphere;

    #[test]
    fn round_trips_within_quantisation() {
        for i in 0..500 {
            let u = [(i as f32 * 0.618_034) % 1.0, (i as f32 * 0.414_213_5) % 1.0];
            let d = uniform_sphere(u);
            let n = uniform_sphere([u[1], u[0]]);
            let c = Color::new(0.3 + u[0], 0.01 * u[1], 2.0) * 1e-4;
            let p = Photon::new(c, d, n);
            assert!(p.direction().dot(d) > 0.999, "dir {d} -> {}", p.direction());
            assert!(p.normal().dot(n) > 0.999, "normal {n} -> {}", p.normal());
            let q = p.power();
            assert!((q - c).abs().max_element() <= c.max_element() / 128.0, "{c} -> {q}");
        }
        assert_eq!(decode_rgbe(encode_rgbe(Color::ZERO)), Color::ZERO);
    }
}
