//! Block comparison of an image with a reference. Averaging over square blocks
//! removes most pixel noise and leaves bias, so block errors show what a method gets
//! wrong systematically (a cache leaking into a contact shadow, a missing glossy
//! lobe), where a per-pixel relative MSE mixes it with noise.

use crate::film::Film;
use anyhow::{Result, bail};

/// One block's comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    /// Block column and row.
    pub at: (u32, u32),
    /// Mean over the block and the three channels, test image.
    pub test: f64,
    /// Same for the reference.
    pub reference: f64,
    /// Standard error of the block's mean difference, from the spread of the per-pixel
    /// differences inside the block (pixel noise of both images).
    pub std_err: f64,
}

impl Block {
    /// Signed relative error (test − reference) / reference.
    pub fn rel(&self) -> f64 {
        (self.test - self.reference) / self.reference
    }
}

/// Summary of a block comparison.
#[derive(Clone, Debug)]
pub struct BlockReport {
    /// Block edge in pixels.
    pub size: u32,
    /// Blocks whose reference mean exceeds the threshold (the others are not judged).
    pub blocks: Vec<Block>,
    /// Ratio of the image means (test / reference), over all pixels and channels.
    pub mean_ratio: f64,
}

impl BlockReport {
    /// The block with the largest |relative error|.
    pub fn worst(&self) -> Option<&Block> {
        self.blocks.iter().max_by(|a, b| a.rel().abs().total_cmp(&b.rel().abs()))
    }
    /// Largest |relative error| (0 when no block is judged).
    pub fn worst_rel(&self) -> f64 {
        self.worst().map_or(0.0, |b| b.rel().abs())
    }
    /// Blocks whose difference exceeds `z` standard errors plus `rel_floor` of the
    /// reference.
    pub fn outliers(&self, z: f64, rel_floor: f64) -> Vec<Block> {
        self.blocks.iter().filter(|b| (b.test - b.reference).abs() > z * b.std_err + rel_floor * b.reference).copied().collect()
    }
}

/// Compares `test` with `reference` over `size`-pixel blocks (partial blocks at the
/// right and bottom edges are dropped), judging blocks whose reference mean exceeds
/// `min_reference`.
pub fn compare_blocks(test: &Film, reference: &Film, size: u32, min_reference: f64) -> Result<BlockReport> {
    compare_blocks_below(test, reference, size, min_reference, f64::INFINITY)
}

/// [`compare_blocks`] that also skips blocks holding a reference pixel brighter than
/// `max_pixel` (mean of its channels): blocks on an emitter's edge, whose error is
/// the sampling of the emitter's outline, not of the light it sheds.
pub fn compare_blocks_below(test: &Film, reference: &Film, size: u32, min_reference: f64, max_pixel: f64) -> Result<BlockReport> {
    if (test.width, test.height) != (reference.width, reference.height) {
        bail!("image sizes differ: {}x{} vs {}x{}", test.width, test.height, reference.width, reference.height);
    }
    if size == 0 {
        bail!("block size must be at least 1");
    }
    let mut blocks = Vec::new();
    for by in 0..reference.height / size {
        for bx in 0..reference.width / size {
            let (mut st, mut sr, mut sd, mut sd2, mut peak) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for y in by * size..(by + 1) * size {
                for x in bx * size..(bx + 1) * size {
                    let (t, r) = (test.get(x, y).as_dvec3(), reference.get(x, y).as_dvec3());
                    let (mt, mr) = (t.element_sum() / 3.0, r.element_sum() / 3.0);
                    peak = peak.max(mr);
                    st += mt;
                    sr += mr;
                    sd += mt - mr;
                    sd2 += (mt - mr) * (mt - mr);
                }
            }
            let n = (size * size) as f64;
            let (mt, mr) = (st / n, sr / n);
            if mr <= min_reference || peak > max_pixel {
                continue;
            }
            let var = if n > 1.0 { ((sd2 - sd * sd / n) / (n - 1.0)).max(0.0) } else { 0.0 };
            blocks.push(Block { at: (bx, by), test: mt, reference: mr, std_err: (var / n).sqrt() });
        }
    }
    let (mt, mr) = (test.mean().as_dvec3().element_sum(), reference.mean().as_dvec3().element_sum());
    Ok(BlockReport { size, blocks, mean_ratio: if mr > 0.0 { mt / mr } else { f64::NAN } })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn finds_a_biased_block_and_ignores_dark_ones() {
        let mut r = Film::new(32, 32);
        for p in &mut r.pixels {
            *p = Vec3::splat(1.0);
        }
        // A dark block the comparison must skip.
        for y in 16..32 {
            for x in 0..16 {
                r.pixels[(y * 32 + x) as usize] = Vec3::ZERO;
            }
        }
        let mut t = r.clone();
        for y in 0..16 {
            for x in 16..32 {
                t.pixels[(y * 32 + x) as usize] *= 1.1;
            }
        }
        let rep = compare_blocks(&t, &r, 16, 0.005).unwrap();
        assert_eq!(rep.blocks.len(), 3);
        let w = rep.worst().unwrap();
        assert_eq!(w.at, (1, 0));
        assert!((w.rel() - 0.1).abs() < 1e-6);
        assert_eq!(rep.outliers(3.0, 0.05).len(), 1);
        assert!(compare_blocks(&t, &Film::new(8, 8), 16, 0.0).is_err());
        // A block with an emitter pixel is skipped on request.
        r.pixels[0] = Vec3::splat(20.0);
        assert_eq!(compare_blocks_below(&t, &r, 16, 0.005, 2.0).unwrap().blocks.len(), 2);
    }
}
