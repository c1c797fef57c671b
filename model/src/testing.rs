//! What the crate's unit tests share.

/// A 64-bit linear congruential generator (Knuth's MMIX constants): reproducible uniform draws in
/// [0, 1) for property tests, with no dependency.
pub(crate) struct Lcg(pub(crate) u64);

impl Lcg {
    /// The next draw, uniform in [0, 1) (the top 53 bits).
    pub(crate) fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}
