//! The plant's seeded noise generator (host: the process's force noise, the chatter model's
//! microphone).

/// SplitMix64 (Steele, Lea and Flood 2014): a fixed, tiny, well-mixed generator.
#[derive(Clone, Debug)]
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Gaussian-ish: the sum of twelve uniforms on [0, 1) minus 6 (mean 0, variance 1, |x| < 6).
    pub(crate) fn gaussish(&mut self) -> f64 {
        (0..12)
            .map(|_| (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
            .sum::<f64>()
            - 6.0
    }
}
