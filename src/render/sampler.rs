//! Deterministic per-pixel random numbers and stratified pixel samples.

/// PCG32 (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient
/// Statistically Good Algorithms for Random Number Generation"), XSH-RR output.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULTIPLIER: u64 = 6364136223846793005;

impl Pcg32 {
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The generator for pixel `(x, y)`: the same sequence whichever thread or
    /// tile renders the pixel (pbrt-v4 `StartPixelSample`).
    pub fn for_pixel(x: u32, y: u32) -> Self {
        Pcg32::new(mix64(((y as u64) << 32) | x as u64), 0x6c69_6e74)
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// Uniform in [0, 1): the top 24 bits scaled by 2⁻²⁴ (exact in f32).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
}

/// SplitMix64's finaliser (Steele et al. 2014): spreads nearby keys apart.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

/// Splits `spp` samples into a `columns × rows` grid of strata, as square as
/// `spp`'s divisors allow (`columns ≤ rows`; a prime count gives 1 × spp strips,
/// still stratified along one axis).
pub fn strata(spp: u32) -> (u32, u32) {
    let mut columns = (spp as f64).sqrt() as u32;
    while columns > 1 && !spp.is_multiple_of(columns) {
        columns -= 1;
    }
    let columns = columns.max(1);
    (columns, spp / columns)
}

/// Offset within the pixel of sample `index` of `spp`: the centre for one
/// sample; otherwise a uniformly jittered point in its stratum.
#[inline]
pub fn pixel_offset(index: u32, spp: u32, rng: &mut Pcg32) -> (f32, f32) {
    if spp == 1 {
        return (0.5, 0.5);
    }
    let (columns, rows) = strata(spp);
    let (i, j) = (index % columns, index / columns);
    (
        (i as f32 + rng.next_f32()) / columns as f32,
        (j as f32 + rng.next_f32()) / rows as f32,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strata_are_as_square_as_possible() {
        assert_eq!(strata(1), (1, 1));
        assert_eq!(strata(4), (2, 2));
        assert_eq!(strata(8), (2, 4));
        assert_eq!(strata(16), (4, 4));
        assert_eq!(strata(7), (1, 7));
    }

    #[test]
    fn each_sample_stays_in_its_stratum() {
        let mut rng = Pcg32::for_pixel(3, 4);
        for s in 0..16 {
            let (u, v) = pixel_offset(s, 16, &mut rng);
            assert_eq!(((u * 4.0) as u32, (v * 4.0) as u32), (s % 4, s / 4));
        }
        assert_eq!(pixel_offset(0, 1, &mut rng), (0.5, 0.5));
    }

    #[test]
    fn pixel_sequences_are_reproducible_and_distinct() {
        let a: Vec<u32> = (0..4).map(|_| Pcg32::for_pixel(5, 9).next_u32()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(
            Pcg32::for_pixel(5, 9).next_u32(),
            Pcg32::for_pixel(9, 5).next_u32()
        );
        let mut r = Pcg32::for_pixel(0, 0);
        let mean = (0..10000).map(|_| r.next_f32() as f64).sum::<f64>() / 10000.0;
        assert!((mean - 0.5).abs() < 0.02, "{mean}");
    }
}
