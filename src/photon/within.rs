//! Radius-bounded photon estimates: every photon within r counts, not the k nearest —
//! the estimator of probabilistic progressive photon mapping (Knaus & Zwicker 2011;
//! SmallVCM's `PPM` and pbrt-v4's SPPM gather the same way). Its bias is the kernel's
//! blur over a disc of radius r and vanishes as r → 0 whatever the photon count,
//! while a k-nearest-neighbour estimate keeps the bias of its own, density-dependent
//! radius until the search limit falls below it.
//!
//! The searches of [`super::estimate::PhotonSearch`] (kd-tree and grid) already stop
//! at the estimate's `max_radius`; asking them for more photons than any disc can
//! hold ([`ALL`]) makes them return every photon inside it, and the estimate divides
//! by π r² of the limit itself (a search returns `max_radius²` when it found fewer
//! than k).

use super::estimate::{EstimateParams, Filter};

/// A photon count no search reaches: "every photon within the radius". `u32::MAX`, so
/// the searches' 2k never overflows.
pub const ALL: usize = u32::MAX as usize;

/// Parameters of a radius-bounded estimate of radius `r` with the estimate filters of
/// [`EstimateParams::new`] (disc thickness, normal test).
pub fn estimate_params(r: f32, filter: Filter, disc: f32) -> EstimateParams {
    EstimateParams::new(ALL, r, filter, disc)
}

/// True when `prm` asks for every photon within its radius.
pub fn is_radius_bounded(prm: &EstimateParams) -> bool {
    prm.k >= ALL
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;
    use crate::photon::estimate::{PhotonSearch, irradiance};
    use crate::photon::kdtree::{KdTree, KnnHeap};
    use crate::photon::nearest::PhotonGrid;
    use crate::photon::record::Photon;
    use glam::Vec3;

    /// A search under test: (r² returned, (distance², power) found, irradiance).
    type Search<'a> = dyn Fn(&mut KnnHeap) -> (f32, Vec<(f32, Color)>, Color) + 'a;

    /// 6000 photons on the two faces of a folded sheet (y = 0 and the plane x = 0.5
    /// standing on it), powers varying with position.
    fn photons() -> (Vec<Vec3>, Vec<Photon>) {
        let (mut pos, mut ph) = (Vec::new(), Vec::new());
        let h = |i: u64, d: u64| crate::math::u32_to_unit((crate::math::hash_words(&[i, d]) >> 32) as u32);
        for i in 0..6000u64 {
            let (a, b) = (h(i, 0), h(i, 1));
            let (p, n) = if i % 3 == 0 { (Vec3::new(0.5, a, b), -Vec3::X) } else { (Vec3::new(a, 0.0, b), Vec3::Y) };
            pos.push(p);
            ph.push(Photon::new(Color::splat(0.5 + h(i, 2)), n, n));
        }
        (pos, ph)
    }

    /// Both searches with [`ALL`] return exactly the photons inside the radius that pass
    /// the estimate's filter (brute force), and return the limit's r²; the irradiance is
    /// Σ Φ w(d²/r²) / (norm π r²) over that set, with more photons than the
    /// k-nearest search of the same call would use.
    #[test]
    fn every_photon_within_the_radius_counts() {
        let (pos, ph) = photons();
        let tree = KdTree::build_with(&pos, ph.clone());
        let stored: Vec<Vec3> = (0..tree.len()).map(|i| tree.position(i)).collect();
        let grid = PhotonGrid::build_photons(&stored, &tree.points, 50);
        let mut heap = KnnHeap::default();
        for (p, n, r) in [
            (Vec3::new(0.3, 0.0, 0.4), Vec3::Y, 0.08f32),
            (Vec3::new(0.45, 0.0, 0.5), Vec3::Y, 0.2),
            (Vec3::new(0.5, 0.3, 0.6), -Vec3::X, 0.15),
        ] {
            let prm = estimate_params(r, Filter::Cone, 0.25);
            assert!(is_radius_bounded(&prm) && !is_radius_bounded(&EstimateParams::new(100, r, Filter::Cone, 0.25)));
            let thick = prm.disc * r;
            let mut want: Vec<(f32, Color)> = (0..tree.len())
                .filter(|&i| {
                    let q = tree.position(i);
                    (q - p).length_squared() < r * r && (q - p).dot(n).abs() <= thick && tree.points[i].normal().dot(n) >= prm.normal_cos
                })
                .map(|i| ((tree.position(i) - p).length_squared(), tree.points[i].power()))
                .collect();
            want.sort_by(|a, b| a.0.total_cmp(&b.0));
            assert!(want.len() > 60, "{} photons", want.len());
            let exact = want.iter().fold(Color::ZERO, |s, (d2, c)| s + *c * prm.filter.weight(d2 / (r * r)))
                / (prm.filter_norm * std::f32::consts::PI * r * r);
            let mut check = |map: &Search| {
                let (r2, mut got, e) = map(&mut heap);
                got.sort_by(|a, b| a.0.total_cmp(&b.0));
                assert_eq!(r2, r * r);
                assert_eq!(got.len(), want.len());
                for (g, w) in got.iter().zip(&want) {
                    assert_eq!(g.0, w.0);
                }
                assert!(((e - exact).abs() / exact).max_element() < 1e-4, "{e} vs {exact}");
            };
            check(&|h| {
                let r2 = tree.gather(p, n, &prm, h);
                let got = h.items.iter().map(|&(d2, i)| (d2, tree.power(i as usize))).collect();
                (r2, got, irradiance(&tree, p, n, &prm, h))
            });
            check(&|h| {
                let r2 = grid.gather(p, n, &prm, h);
                let got = h.items.iter().map(|&(d2, i)| (d2, grid.power(i as usize))).collect();
                (r2, got, irradiance(&grid, p, n, &prm, h))
            });
            // The k-nearest search of the same radius stops at 50 photons and its own radius.
            let knn = EstimateParams::new(50, r, Filter::Cone, 0.25);
            let r2 = grid.gather(p, n, &knn, &mut heap);
            assert!(heap.items.len() == 50 && r2 < r * r);
        }
    }
}
