//! Random numbers: a progressive Owen-scrambled Sobol sampler for pixel
//! samples, seeded by (pixel, sample number), and PCG32 for everything else
//! (tests, benchmarks).

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

/// Burley's hash-based nested uniform (Owen) scrambling of a bit-reversed
/// value (Burley 2020, "Practical Hash-based Owen Scrambling", JCGT 9(4)):
/// each bit of `x` is flipped by a hash of the bits below it, so the
/// scrambled value of a bit-reversed coordinate has each digit permuted
/// depending only on the more significant digits, as Owen (1995) asks.
#[inline(always)]
fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen scrambling of a 0.32 fixed-point coordinate with `seed` (the
/// definition [`pair_bits_reversed`] computes with fewer reversals).
#[cfg(test)]
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()
}

/// The direction numbers of Sobol's second dimension (primitive polynomial
/// `x + 1`) as 0.32 fixed point: `v₀ = 2³¹`, `vₖ = vₖ₋₁ ⊕ (vₖ₋₁ ≫ 1)`.
const fn sobol_directions() -> [u32; 32] {
    let mut v = [0u32; 32];
    let mut k = 0;
    let mut d = 1u32 << 31;
    while k < 32 {
        v[k] = d;
        d ^= d >> 1;
        k += 1;
    }
    v
}

/// For each byte of an index and each of its 256 values, the XOR of the
/// direction numbers of its set bits: four lookups give a point, instead of
/// a loop over 32 bits (the shuffled indices use all of them).
const SOBOL_BYTES: [[u32; 256]; 4] = {
    let v = sobol_directions();
    let mut t = [[0u32; 256]; 4];
    let mut byte = 0;
    while byte < 4 {
        let mut value = 0;
        while value < 256 {
            let mut x = 0;
            let mut bit = 0;
            while bit < 8 {
                if value & (1 << bit) != 0 {
                    x ^= v[byte * 8 + bit];
                }
                bit += 1;
            }
            t[byte][value] = x;
            value += 1;
        }
        byte += 1;
    }
    t
};

/// The first two dimensions of Sobol's sequence (Sobol 1967), as 0.32
/// fixed-point numbers: the van der Corput radical inverse, and the dimension
/// with primitive polynomial `x + 1` (point `i` is the XOR of the direction
/// numbers of `i`'s set bits, natural order). Every aligned block of 2^m
/// consecutive points is a (0, m, 2)-net in base 2.
#[cfg(test)]
pub fn sobol_2d(index: u32) -> (u32, u32) {
    let [b0, b1, b2, b3] = index.to_le_bytes();
    let y = SOBOL_BYTES[0][b0 as usize]
        ^ SOBOL_BYTES[1][b1 as usize]
        ^ SOBOL_BYTES[2][b2 as usize]
        ^ SOBOL_BYTES[3][b3 as usize];
    (index.reverse_bits(), y)
}

/// A 0.32 fixed-point number as an f32 in [0, 1): its top 24 bits, exactly.
#[inline(always)]
fn unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The random numbers of one sample of one pixel: a progressive Owen-scrambled
/// Sobol sequence, seeded by the pixel and indexed by the sample's number.
///
/// Everything depends only on `(x, y, index)`, never on how many samples the
/// render takes, which tile holds the pixel, or which thread renders it; so
/// samples `0..32` and `32..64` rendered apart are exactly samples `0..64`.
///
/// Each pair of dimensions is a 2-D Sobol point with its own scramble, its
/// sample order shuffled by a nested uniform scramble of the index (Burley
/// 2020, §4; as pbrt-v4's padded Sobol sampler, but without its dependence
/// on the sample count). The index scramble maps each aligned block of 2^m
/// indices onto another, so any prefix of 2^m samples of a pixel is a
/// (0, m, 2)-net in each pair of dimensions: well stratified at every count.
#[derive(Clone, Debug)]
pub struct PixelSampler {
    /// The pixel's coordinates, packed (see [`pixel_key`]).
    key: u64,
    /// Its seed, hashed from `key` when first needed (many integrators
    /// never draw a number: ray casting with point lights).
    seed: Option<u64>,
    index: u32,
    /// `index` bit-reversed, shared by every pair.
    reversed: u32,
    /// The next dimension pair to hand out (0 is the pixel offset).
    pair: u32,
}

impl PixelSampler {
    /// The sampler of sample `index` of pixel `(x, y)`.
    pub fn new(x: u32, y: u32, index: u32) -> Self {
        PixelSampler {
            key: pixel_key(x, y),
            seed: None,
            index,
            reversed: index.reverse_bits(),
            pair: 1,
        }
    }

    /// Where in the pixel the sample lies (see [`PixelSamples::offset`]).
    /// To take many samples of one pixel, [`PixelSamples`] is faster.
    pub fn pixel_offset(&self) -> (f32, f32) {
        PixelSamples::from_key(self.key).offset(self.index)
    }

    /// The next two dimensions, in [0, 1)².
    #[inline]
    pub fn next_2d(&mut self) -> (f32, f32) {
        // The pair's three scrambles from one 64-bit hash (the pixel offset's
        // pair, in `PixelSamples`, keeps its own three).
        let key = self.key;
        let seed = *self.seed.get_or_insert_with(|| mix64(key));
        let h = mix64(seed ^ (self.pair as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let seeds = [
            h as u32,
            (h >> 32) as u32,
            (h.wrapping_mul(0xd6e8_feb8_6659_fd93) >> 32) as u32,
        ];
        let (a, b) = pair_bits_reversed(&seeds, self.reversed);
        self.pair += 1;
        (unit_f32(a), unit_f32(b))
    }

    /// The next dimension, in [0, 1) (a pair of its own).
    pub fn next_1d(&mut self) -> f32 {
        self.next_2d().0
    }
}

/// How many pixel offsets [`PixelSamples::offsets`] computes together.
pub const OFFSET_LANES: usize = 8;

/// The samples of one pixel, with what they share computed once: the
/// scrambles of the pixel-offset dimensions and the digital shift that puts
/// sample 0 at the pixel's centre (both only when a sample other than 0 is
/// asked for: one sample per pixel costs nothing).
#[derive(Clone, Copy, Debug)]
pub struct PixelSamples {
    /// The pixel's coordinates, packed (see [`pixel_key`]).
    key: u64,
    /// The scrambles and the shift, once computed.
    scrambles: Option<([u32; 3], (u32, u32))>,
}

impl PixelSamples {
    pub fn new(x: u32, y: u32) -> Self {
        PixelSamples::from_key(pixel_key(x, y))
    }

    fn from_key(key: u64) -> Self {
        PixelSamples {
            key,
            scrambles: None,
        }
    }

    /// Where in the pixel sample `index` lies, in [0, 1)². Sample 0 is the
    /// pixel's centre (so one sample per pixel shoots through centres, as
    /// ray casting does): the pixel's points are digitally shifted (each
    /// XORed with one constant) to put it there, which keeps every
    /// (0, m, 2)-net a net.
    #[inline]
    pub fn offset(&mut self, index: u32) -> (f32, f32) {
        if index == 0 {
            // What the shift makes of sample 0, without computing it.
            return (0.5, 0.5);
        }
        let (scrambles, shift) = self.scrambles();
        let (a, b) = pair_bits(&scrambles, index);
        (unit_f32(a ^ shift.0), unit_f32(b ^ shift.1))
    }

    /// [`PixelSamples::offset`] of samples `start..start + out.len()`,
    /// into `out`, bit for bit, computed [`OFFSET_LANES`] at a time in
    /// the widest vector unit the CPU has: the permutations are
    /// multiplications and XORs, and the bit reversals byte shuffles,
    /// where one sample at a time they are long chains of scalar
    /// operations (a pixel's offsets took more time than its camera
    /// rays' traversal in an 8-sample mesh render). Integer operations
    /// only, so every lane is exactly the one-sample value.
    pub fn offsets(&mut self, start: u32, out: &mut [(f32, f32)]) {
        if let [one] = out {
            *one = self.offset(start);
            return;
        }
        // What the shift makes of sample 0, as `offset`.
        let (index, out) = match out.split_first_mut() {
            Some((first, rest)) if start == 0 => {
                *first = (0.5, 0.5);
                (1, rest)
            }
            _ => (start, out),
        };
        if out.is_empty() {
            return;
        }
        let (scrambles, shift) = self.scrambles();
        crate::scene::widest(
            #[inline(always)]
            || {
                for (c, chunk) in out.chunks_mut(OFFSET_LANES).enumerate() {
                    let first = index.wrapping_add((c * OFFSET_LANES) as u32);
                    let mut a = [0u32; OFFSET_LANES];
                    let mut b = [0u32; OFFSET_LANES];
                    for j in 0..OFFSET_LANES {
                        (a[j], b[j]) = pair_bits(&scrambles, first.wrapping_add(j as u32));
                    }
                    for (o, (a, b)) in chunk.iter_mut().zip(a.iter().zip(&b)) {
                        *o = (unit_f32(a ^ shift.0), unit_f32(b ^ shift.1));
                    }
                }
            },
        )
    }

    /// The scrambles of the pixel-offset dimensions and the digital shift,
    /// computed on first use.
    #[inline(always)]
    fn scrambles(&mut self) -> ([u32; 3], (u32, u32)) {
        let key = self.key;
        *self.scrambles.get_or_insert_with(|| {
            let scrambles = pair_seeds(mix64(key), 0);
            let (a0, b0) = pair_bits(&scrambles, 0);
            let half = 1u32 << 31;
            (scrambles, (a0 ^ half, b0 ^ half))
        })
    }

    /// The sampler of sample `index`, for the dimensions after the pixel
    /// offset.
    pub fn sampler(&self, index: u32) -> PixelSampler {
        PixelSampler {
            key: self.key,
            seed: None,
            index,
            reversed: index.reverse_bits(),
            pair: 1,
        }
    }
}

/// Pixel `(x, y)` as one number, whose hash is its seed.
#[inline]
fn pixel_key(x: u32, y: u32) -> u64 {
    ((y as u64) << 32) | x as u64
}

/// The seed of pixel `(x, y)`.
#[cfg(test)]
fn pixel_seed(x: u32, y: u32) -> u64 {
    mix64(pixel_key(x, y))
}

/// The scrambles of dimension pair `pair` of a pixel: the two coordinates'
/// and the index shuffle's.
#[inline]
fn pair_seeds(pixel: u64, pair: u32) -> [u32; 3] {
    let seed = |k: u64| {
        (mix64(pixel ^ ((pair as u64) << 2 | k).wrapping_mul(0x9e37_79b9_7f4a_7c15)) >> 32) as u32
    };
    [seed(0), seed(1), seed(2)]
}

/// A dimension pair of sample `index`, as 0.32 fixed point: the index
/// shuffled, its 2-D Sobol point, each coordinate scrambled.
#[inline(always)]
fn pair_bits(seeds: &[u32; 3], index: u32) -> (u32, u32) {
    pair_bits_reversed(seeds, index.reverse_bits())
}

/// [`pair_bits`] given the index bit-reversed, with the reversals that
/// cancel left out: the shuffled index is `rev(LK(rev(i)))`, its first
/// Sobol coordinate `rev(shuffled)`, so that coordinate's scramble
/// `rev(LK(rev(rev(shuffled))))` needs `shuffled` itself; the second
/// coordinate comes bit-reversed from a table. Three reversals instead of
/// seven; the same bits.
#[inline(always)]
fn pair_bits_reversed(seeds: &[u32; 3], reversed_index: u32) -> (u32, u32) {
    let shuffled = laine_karras_permutation(reversed_index, seeds[2]).reverse_bits();
    let [b0, b1, b2, b3] = shuffled.to_le_bytes();
    let b_reversed = SOBOL_BYTES_REVERSED[0][b0 as usize]
        ^ SOBOL_BYTES_REVERSED[1][b1 as usize]
        ^ SOBOL_BYTES_REVERSED[2][b2 as usize]
        ^ SOBOL_BYTES_REVERSED[3][b3 as usize];
    (
        laine_karras_permutation(shuffled, seeds[0]).reverse_bits(),
        laine_karras_permutation(b_reversed, seeds[1]).reverse_bits(),
    )
}

/// [`SOBOL_BYTES`] with every entry bit-reversed.
const SOBOL_BYTES_REVERSED: [[u32; 256]; 4] = {
    let mut t = SOBOL_BYTES;
    let mut byte = 0;
    while byte < 4 {
        let mut value = 0;
        while value < 256 {
            t[byte][value] = t[byte][value].reverse_bits();
            value += 1;
        }
        byte += 1;
    }
    t
};

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples `[start, start + n)` of pixel `(x, y)`: how many fall in
    /// each of the `n` cells of every elementary-interval shape of area 1/n.
    fn assert_net(x: u32, y: u32, start: u32, n: u32) {
        // The pixel offset, and the first and third pairs after it.
        for pair in [0, 1, 3] {
            let points: Vec<(f32, f32)> = (start..start + n)
                .map(|i| {
                    let mut s = PixelSampler::new(x, y, i);
                    if pair == 0 {
                        return s.pixel_offset();
                    }
                    for _ in 1..pair {
                        s.next_2d();
                    }
                    s.next_2d()
                })
                .collect();
            assert_points_net(&points, x, y, start, n, pair);
        }
    }

    fn assert_points_net(points: &[(f32, f32)], x: u32, y: u32, start: u32, n: u32, pair: u32) {
        let m = n.trailing_zeros();
        for j in 0..=m {
            let (cols, rows) = (1u32 << j, 1u32 << (m - j));
            let mut cells = vec![0u32; n as usize];
            for &(u, v) in points {
                let c = (u * cols as f32) as u32 + cols * (v * rows as f32) as u32;
                cells[c as usize] += 1;
            }
            assert!(
                cells.iter().all(|&c| c == 1),
                "pair {pair} of samples {start}..{} of ({x},{y}) is not stratified in {cols}×{rows} cells",
                start + n
            );
        }
    }

    #[test]
    fn every_power_of_two_block_is_a_net() {
        for (x, y) in [(0, 0), (5, 9), (1919, 1079)] {
            for m in 0..=8 {
                let n = 1 << m;
                assert_net(x, y, 0, n);
                assert_net(x, y, n, n);
                assert_net(x, y, 3 * n, n);
            }
        }
    }

    /// The shortcut computes the definition: shuffle the index, take its
    /// Sobol point, scramble each coordinate.
    #[test]
    fn pair_bits_is_the_scrambled_shuffled_sobol_point() {
        let mut rng = Pcg32::new(11, 12);
        for _ in 0..100_000 {
            let seeds = [rng.next_u32(), rng.next_u32(), rng.next_u32()];
            let index = rng.next_u32() >> (rng.next_u32() % 32);
            let (a, b) = sobol_2d(owen_scramble(index, seeds[2]));
            let expect = (owen_scramble(a, seeds[0]), owen_scramble(b, seeds[1]));
            assert_eq!(pair_bits(&seeds, index), expect, "index {index}");
        }
    }

    #[test]
    fn offsets_together_are_each_offset_alone() {
        let mut rng = Pcg32::new(21, 4);
        for _ in 0..2000 {
            let (x, y) = (rng.next_u32() % 5000, rng.next_u32() % 5000);
            // Ranges from sample 0 and from further on, of every length
            // around the lane count, and some near the end of u32.
            let start = match rng.next_u32() % 4 {
                0 => 0,
                1 => rng.next_u32() % 64,
                2 => rng.next_u32(),
                _ => u32::MAX - rng.next_u32() % 40,
            };
            let len = (rng.next_u32() % (5 * OFFSET_LANES as u32)) as usize;
            let len = len.min((u32::MAX - start) as usize + 1);
            let mut together = vec![(f32::NAN, f32::NAN); len];
            PixelSamples::new(x, y).offsets(start, &mut together);
            let mut alone = PixelSamples::new(x, y);
            for (k, got) in together.iter().enumerate() {
                let want = alone.offset(start + k as u32);
                assert_eq!(
                    (got.0.to_bits(), got.1.to_bits()),
                    (want.0.to_bits(), want.1.to_bits()),
                    "pixel ({x}, {y}), sample {}",
                    start + k as u32
                );
            }
        }
    }

    #[test]
    fn sample_zero_is_the_pixel_centre() {
        // The shortcut for sample 0 is what the shift gives.
        for (x, y) in [(0, 0), (7, 3), (640, 480)] {
            let scrambles = pair_seeds(pixel_seed(x, y), 0);
            let (a0, b0) = pair_bits(&scrambles, 0);
            let half = 1u32 << 31;
            let (a, b) = (a0 ^ (a0 ^ half), b0 ^ (b0 ^ half));
            assert_eq!((unit_f32(a), unit_f32(b)), (0.5, 0.5));
        }
        for (x, y) in [(0, 0), (7, 3), (640, 480)] {
            assert_eq!(PixelSampler::new(x, y, 0).pixel_offset(), (0.5, 0.5));
        }
        assert_ne!(PixelSampler::new(7, 3, 1).pixel_offset(), (0.5, 0.5));
        let mut p = PixelSamples::new(7, 3);
        for i in [0, 1, 5, 1000] {
            assert_eq!(p.offset(i), PixelSampler::new(7, 3, i).pixel_offset());
        }
        let (mut a, mut b) = (p.sampler(9), PixelSampler::new(7, 3, 9));
        assert_eq!(a.next_2d(), b.next_2d());
    }

    #[test]
    fn sobol_matches_the_published_sequence() {
        let to_f = |x: u32| x as f64 / 4294967296.0;
        let second: Vec<f64> = (0..8).map(|i| to_f(sobol_2d(i).1)).collect();
        // Natural (not Gray-code) order: point i is the XOR of the direction
        // numbers of i's set bits.
        assert_eq!(second, [0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875]);
        let first: Vec<f64> = (0..4).map(|i| to_f(sobol_2d(i).0)).collect();
        assert_eq!(first, [0.0, 0.5, 0.25, 0.75]);
        // The tables agree with the bit-by-bit definition.
        let v = sobol_directions();
        let mut r = Pcg32::new(1, 2);
        for i in (0..1000).chain((0..1000).map(|_| r.next_u32())) {
            let y = (0..32).filter(|k| i >> k & 1 != 0).fold(0, |y, k| y ^ v[k]);
            assert_eq!(sobol_2d(i).1, y, "{i}");
        }
    }

    #[test]
    fn pixels_and_dimensions_are_decorrelated() {
        let a = PixelSampler::new(1, 2, 5).pixel_offset();
        let b = PixelSampler::new(2, 1, 5).pixel_offset();
        assert_ne!(a, b);
        let mut s = PixelSampler::new(1, 2, 5);
        let (d1, d2) = (s.next_2d(), s.next_2d());
        assert_ne!(d1, d2);
        // Higher dimensions are uniform and stratified too.
        let n = 256;
        let mut cells = vec![0; 16];
        let mut mean = 0.0;
        for i in 0..n {
            let mut s = PixelSampler::new(3, 4, i);
            s.next_2d();
            let (u, v) = s.next_2d();
            mean += (u + v) as f64 / (2 * n) as f64;
            cells[(u * 4.0) as usize + 4 * (v * 4.0) as usize] += 1;
        }
        assert!(cells.iter().all(|&c| c == 16), "{cells:?}");
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
    }

    #[test]
    fn pcg_is_reproducible_and_uniform() {
        let a: Vec<u32> = (0..4).map(|_| Pcg32::new(5, 9).next_u32()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(Pcg32::new(5, 9).next_u32(), Pcg32::new(9, 5).next_u32());
        let mut r = Pcg32::new(0, 0);
        let mean = (0..10000).map(|_| r.next_f32() as f64).sum::<f64>() / 10000.0;
        assert!((mean - 0.5).abs() < 0.02, "{mean}");
    }
}
