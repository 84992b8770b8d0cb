//! `precomputed`: final gathering whose hits look up Christensen's precomputed
//! irradiance (2000, [`crate::photon::irradiance`]) instead of a full photon
//! estimate: irradiance estimated at every `precompute_stride`-th stored photon before
//! rendering; a lookup takes the nearest point on the side the hit is seen from.

crate::params! {
    /// Christensen's precomputed irradiance (read by `precomputed`, and by
    /// `irradiance_cache` with `precomputed_irradiance`).
    pub struct PrecomputedParams {
        /// Precompute irradiance at every n-th stored photon.
        precompute_stride: u32 = "4",
    }
}

impl PrecomputedParams {
    /// Reads and checks the parameters.
    pub fn read_checked(r: &crate::param::Reader) -> anyhow::Result<Self> {
        let p = Self::read(r)?;
        if p.precompute_stride == 0 {
            anyhow::bail!("precompute_stride must be at least 1");
        }
        Ok(p)
    }
}

/// The `precomputed` plug-in: the final gather of [`super::final_gather`] whose rays
/// read precomputed irradiance where they land.
pub fn gather() -> super::final_gather::FinalGather {
    super::final_gather::FinalGather { over_precomputed: true }
}
