//! Independent uniform random numbers, deterministic per (seed, pixel, sample index).
//!
//! Every camera sample owns a PCG32 stream whose state is a hash of the three indices, so an image
//! is bit-identical whatever the number of threads or the order in which tiles are rendered.
//! Independent (not low-discrepancy) numbers are deliberate: the variance estimates the
//! project measures assume independent samples.

use glam::Vec2;
use rand_core::Rng;
use rand_pcg::Pcg32;

/// A random number generator for one camera sample of one pixel.
#[derive(Clone, Debug)]
pub struct Sampler {
    rng: Pcg32,
}

/// SplitMix64 finaliser: a bijective scrambling of 64-bit words.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Sampler {
    /// The stream of sample `sample_index` of the pixel with linear index `pixel_index`.
    pub fn new(seed: u64, pixel_index: u64, sample_index: u64) -> Self {
        let state = mix64(seed ^ mix64(pixel_index.wrapping_add(0x9e37_79b9_7f4a_7c15)));
        let stream = mix64(sample_index ^ mix64(seed.wrapping_add(0x632b_e59b_d9b4_e019)));
        Sampler {
            rng: Pcg32::new(state, stream),
        }
    }

    /// A uniform number in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        (self.rng.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Skips `count` numbers, as `count` calls of `next_1d` would.
    #[inline]
    pub fn skip(&mut self, count: u32) {
        for _ in 0..count {
            self.rng.next_u32();
        }
    }

    /// Two uniform numbers in [0, 1)².
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        Vec2::new(x, self.next_1d())
    }

    /// One of `values`, each as likely, from one number (for tests that mix special values
    /// into random ones).
    #[cfg(test)]
    pub(crate) fn pick<T: Copy>(&mut self, values: &[T]) -> T {
        values[(self.next_1d() * values.len() as f32) as usize % values.len()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skipping_is_drawing_and_discarding() {
        let (mut skipped, mut drawn) = (Sampler::new(7, 123, 4), Sampler::new(7, 123, 4));
        skipped.skip(5);
        for _ in 0..5 {
            drawn.next_1d();
        }
        assert_eq!(skipped.next_1d().to_bits(), drawn.next_1d().to_bits());
    }

    #[test]
    fn same_indices_same_numbers() {
        let mut a = Sampler::new(7, 123, 4);
        let mut b = Sampler::new(7, 123, 4);
        for _ in 0..100 {
            assert_eq!(a.next_1d().to_bits(), b.next_1d().to_bits());
        }
    }

    #[test]
    fn different_indices_differ_and_stay_in_unit_interval() {
        let firsts: Vec<f32> = (0..64)
            .flat_map(|p| (0..4).map(move |s| Sampler::new(1, p, s).next_1d()))
            .collect();
        let mut sorted = firsts.clone();
        sorted.sort_by(f32::total_cmp);
        sorted.dedup();
        assert_eq!(sorted.len(), firsts.len(), "streams collide");
        assert!(firsts.iter().all(|u| (0.0..1.0).contains(u)));
        // The mean of 256 uniforms is within 4 sigma (sigma = sqrt(1/12/256) = 0.018) of 1/2.
        let mean = firsts.iter().sum::<f32>() / firsts.len() as f32;
        assert!((mean - 0.5).abs() < 4.0 * 0.018, "mean {mean}");
    }
}
