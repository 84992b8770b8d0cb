//! Per-technique images (`--aov strategies`, as pbrt's BDPT `visualizestrategies` /
//! `visualizeweights`): for each (s, t) technique that contributed, its weighted
//! contribution (`sS-tT`) and its unweighted one (`sS-tT-unweighted`, the technique
//! alone), and for `vcm` the merging part (`merge`). Weighted images of one path
//! length add up to that length's share of the image.

use super::eye::MERGE;
use super::pass::Item;
use crate::film::Film;
use glam::DVec3;
use std::collections::BTreeMap;

/// Longest path (edges) shown per technique; longer ones only in the full image.
pub const MAX_SHOWN_LENGTH: u32 = 5;

/// Sums of weighted and unweighted contributions per technique.
#[derive(Default)]
pub struct Strategies {
    images: BTreeMap<(u32, u32), (Vec<DVec3>, Vec<DVec3>)>,
}

impl Strategies {
    /// Adds one pass's items for an image of `npix` pixels.
    pub fn add(&mut self, items: &[Item], npix: usize) {
        for it in items {
            if it.s != MERGE && it.s + it.t > MAX_SHOWN_LENGTH + 1 {
                continue;
            }
            let key = if it.s == MERGE { (MERGE, 0) } else { (it.s, it.t) };
            let e = self.images.entry(key).or_insert_with(|| (vec![DVec3::ZERO; npix], vec![DVec3::ZERO; npix]));
            let v = it.value.as_dvec3();
            e.0[it.pixel as usize] += v;
            if it.weight > 0.0 {
                e.1[it.pixel as usize] += v / it.weight as f64;
            }
        }
    }

    /// The images after `passes` passes.
    pub fn images(&self, w: u32, h: u32, passes: u32) -> Vec<(String, Film)> {
        let film = |v: &[DVec3]| Film { width: w, height: h, pixels: v.iter().map(|p| (*p / passes.max(1) as f64).as_vec3()).collect() };
        let mut out = Vec::new();
        for (&(s, t), (wt, un)) in &self.images {
            if s == MERGE {
                out.push(("merge".to_string(), film(wt)));
            } else {
                out.push((format!("s{s}-t{t}"), film(wt)));
                out.push((format!("s{s}-t{t}-unweighted"), film(un)));
            }
        }
        out
    }
}
