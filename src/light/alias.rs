//! Walker's alias method: sampling a discrete distribution in O(1).

/// A discrete distribution over `0..n` with probabilities proportional to
/// given weights, sampled in constant time (Walker 1977, with Vose's 1991
/// construction, which is exact for any weights).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AliasTable {
    /// Per bin: the probability of keeping it, and its alias.
    bins: Vec<(f32, u32)>,
    /// The normalised probability of each index.
    pmf: Vec<f32>,
}

impl AliasTable {
    /// The table of `weights` (finite, ≥ 0). All-zero or empty weights give
    /// an empty table, which samples nothing.
    pub fn new(weights: &[f64]) -> Self {
        let total: f64 = weights.iter().sum();
        if weights.is_empty() || !(total > 0.0 && total.is_finite()) {
            return AliasTable::default();
        }
        let n = weights.len();
        let pmf: Vec<f64> = weights.iter().map(|w| w / total).collect();
        let mut scaled: Vec<f64> = pmf.iter().map(|p| p * n as f64).collect();
        let mut bins = vec![(1.0f32, 0u32); n];
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            bins[s] = (scaled[s] as f32, l as u32);
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // What is left holds probability 1 up to rounding.
        for i in small.into_iter().chain(large) {
            bins[i] = (1.0, i as u32);
        }
        AliasTable {
            bins,
            pmf: pmf.into_iter().map(|p| p as f32).collect(),
        }
    }

    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// The probability of index `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf.get(i).copied().unwrap_or(0.0)
    }

    /// [`AliasTable::sample`], also returning `u` remapped to a uniform
    /// number in [0, 1) within the part of [0, 1) that chose the index, so
    /// that one uniform number both chooses and samples (points stratified
    /// in `u` stay stratified within each index's share).
    #[inline]
    pub fn sample_remapped(&self, u: f32) -> Option<(usize, f32, f32)> {
        if self.bins.is_empty() {
            return None;
        }
        let n = self.bins.len();
        let x = u * n as f32;
        let bin = (x as usize).min(n - 1);
        let rest = x - bin as f32;
        let (keep, alias) = self.bins[bin];
        let (i, v) = if rest < keep {
            (bin, rest / keep)
        } else {
            (alias as usize, (rest - keep) / (1.0 - keep))
        };
        Some((i, self.pmf[i], v.clamp(0.0, 1.0 - f32::EPSILON / 2.0)))
    }

    /// An index for `u ∈ [0, 1)`, with its probability; `None` if empty.
    #[inline]
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        if self.bins.is_empty() {
            return None;
        }
        let n = self.bins.len();
        let x = u * n as f32;
        let bin = (x as usize).min(n - 1);
        let rest = x - bin as f32;
        let (keep, alias) = self.bins[bin];
        let i = if rest < keep { bin } else { alias as usize };
        Some((i, self.pmf[i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frequencies_follow_the_weights() {
        let w = [1.0, 0.0, 3.0, 0.5, 10.0, 0.25];
        let table = AliasTable::new(&w);
        let total: f64 = w.iter().sum();
        let n = 1_000_000;
        let mut counts = [0u32; 6];
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32;
            let (i, p) = table.sample(u).unwrap();
            assert_eq!(p, table.pmf(i));
            counts[i] += 1;
        }
        for i in 0..6 {
            let expect = w[i] / total;
            let got = counts[i] as f64 / n as f64;
            assert!((got - expect).abs() < 1e-4, "{i}: {got} vs {expect}");
            assert!((table.pmf(i) as f64 - expect).abs() < 1e-6);
        }
        assert_eq!(counts[1], 0);
    }

    #[test]
    fn remapped_numbers_stay_uniform() {
        let table = AliasTable::new(&[1.0, 3.0, 0.5]);
        let n = 300_000;
        let mut hist = [[0u32; 10]; 3];
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32;
            let (i, p, v) = table.sample_remapped(u).unwrap();
            assert_eq!(p, table.pmf(i));
            assert!((0.0..1.0).contains(&v));
            hist[i][(v * 10.0) as usize] += 1;
        }
        for (i, h) in hist.iter().enumerate() {
            let total: u32 = h.iter().sum();
            for &c in h {
                let f = c as f64 / total as f64;
                assert!((f - 0.1).abs() < 0.01, "index {i}: {h:?}");
            }
        }
    }

    #[test]
    fn nothing_to_sample() {
        assert!(AliasTable::new(&[]).sample(0.5).is_none());
        assert!(AliasTable::new(&[0.0, 0.0]).sample(0.5).is_none());
    }
}
