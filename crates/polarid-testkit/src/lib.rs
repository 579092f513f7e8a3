//! Helpers shared by polarid's integration tests: a dev-dependency of every crate, never
//! a dependency of the product.
//!
//! - [`Rng`]: a small deterministic generator (SplitMix64 with Box–Muller normal
//!   deviates), so that the tests need no random-number dependency and their streams
//!   stay the same across versions of `rand`;
//! - [`full`] and [`seeds`]: the size of the statistical studies (quick by default, full
//!   size with `POLARID_FULL=1`); [`max_misses`] ([`binomial_sf`]): how many misses a
//!   quick-size study may see under its claimed rate;
//! - [`note!`]: a line on the terminal that the test harness does not capture (a test
//!   on the independent renders says so when `POLARID_RENDERS` is not set);
//! - [`calibrated_bench`]: a synthetic calibrated bench (perspective camera, lamps at a
//!   finite distance, noisy Stokes images).

pub mod calibrated_bench;

use std::io::Write;

/// SplitMix64's output function (Steele, Lea & Flood, "Fast splittable pseudorandom
/// number generators", OOPSLA 2014).
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A SplitMix64 stream with uniform and Gaussian (Box–Muller) draws.
///
/// `Rng(state)` starts the stream at the raw state `state`; [`Rng::new`] hashes a seed
/// first, so that the streams of nearby seeds do not overlap.
#[derive(Debug, Clone)]
pub struct Rng(pub u64);

impl Rng {
    /// Seeded generator: the seed is hashed into the state.
    pub fn new(seed: u64) -> Self {
        Self(mix(seed ^ 0xD1B5_4A32_D192_ED03).wrapping_add(mix(seed.wrapping_add(1))))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix(self.0)
    }

    /// Uniform in the open interval (0, 1): the midpoints of 2⁵³ equal cells.
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Uniform in [0, 1): multiples of 2⁻⁵³.
    pub fn uniform_co(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi) (from [`Rng::uniform_co`]).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform_co()
    }

    /// Standard normal deviate (Box–Muller, cosine branch) from two [`Rng::uniform`]
    /// draws.
    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Standard normal deviate (Box–Muller, cosine branch) from two
    /// [`Rng::uniform_co`] draws, the first kept above 10⁻³⁰⁰.
    pub fn normal_co(&mut self) -> f64 {
        let u1 = self.uniform_co().max(1e-300);
        let u2 = self.uniform_co();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// True when `POLARID_FULL` is set to anything but `0` or the empty string: run the
/// statistical studies at full size (CI does, after the quick suite).
pub fn full() -> bool {
    std::env::var_os("POLARID_FULL").is_some_and(|v| !v.is_empty() && v != "0")
}

/// `full_size` with `POLARID_FULL=1`, else `quick`: the number of seeds (trials,
/// targets, ...) of a statistical study.
pub fn seeds(quick: u64, full_size: u64) -> u64 {
    if full() { full_size } else { quick }
}

/// `P(X ≥ k)` for `X ~ Binomial(n, p)` (summed in log space: no underflow for the
/// sample sizes of the studies).
pub fn binomial_sf(k: u64, n: u64, p: f64) -> f64 {
    if k == 0 {
        return 1.0;
    }
    if k > n || p <= 0.0 {
        return 0.0;
    }
    if p >= 1.0 {
        return 1.0;
    }
    let (lp, lq) = (p.ln(), (-p).ln_1p());
    // ln P(X = i), from ln P(X = 0) = n ln(1 − p).
    let mut l = n as f64 * lq;
    let mut sum = 0.0;
    for i in 0..=n {
        if i >= k {
            sum += l.exp();
        }
        l += ((n - i) as f64 / (i + 1) as f64).ln() + lp - lq;
    }
    sum.min(1.0)
}

/// The most misses (wrong answers, or values outside a stated interval) among `n` trials
/// that a rule whose miss rate is at most `rate` still makes with probability at least
/// `alpha` (the largest `m` with `P(X ≥ m) ≥ alpha`, `X ~ Binomial(n, rate)`): a study
/// run at a quick size asserts `misses <= max_misses(n, rate, 1e-3)` for a claim "at least
/// `1 − rate` right", which a few seeds cannot test as a plain fraction, and its full
/// size (`POLARID_FULL=1`) the fraction itself.
pub fn max_misses(n: u64, rate: f64, alpha: f64) -> u64 {
    (1..=n)
        .take_while(|&m| binomial_sf(m, n, rate) >= alpha)
        .last()
        .unwrap_or(0)
}

/// Writes `msg` on the terminal even while the test harness captures the output of
/// passing tests (it captures `print!`/`eprint!`, not direct writes to stderr).
pub fn note(msg: &str) {
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{msg}");
}

/// `note!("...", args)`: [`note()`] with `format!` arguments, prefixed with the module of
/// the test (`it::map_cmd: ...`), e.g. when a test on the independent renders is skipped
/// because `POLARID_RENDERS` is not set.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::note(&format!("{}: {}", module_path!(), format_args!($($arg)*)))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_draws_lie_in_their_intervals_and_normals_have_unit_variance() {
        let mut r = Rng::new(7);
        let n = 100_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let u = r.uniform();
            assert!(u > 0.0 && u < 1.0);
            let v = r.uniform_co();
            assert!((0.0..1.0).contains(&v));
            let z = r.normal();
            s += z;
            s2 += z * z;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        // 5 standard errors: mean se 1/√n = 0.0032, variance se √(2/n) = 0.0045.
        assert!(mean.abs() < 0.016, "{mean}");
        assert!((var - 1.0).abs() < 0.023, "{var}");
    }

    #[test]
    fn binomial_tail_and_miss_bound() {
        // P(X ≥ 1) = 1 − (1 − p)^n; P(X ≥ n) = p^n; the whole distribution sums to 1.
        assert!((binomial_sf(1, 10, 0.5) - (1.0 - 0.5f64.powi(10))).abs() < 1e-14);
        assert!((binomial_sf(10, 10, 0.5) - 0.5f64.powi(10)).abs() < 1e-15);
        assert!((binomial_sf(0, 600, 0.01) - 1.0).abs() < 1e-12);
        assert!((binomial_sf(3, 60, 0.01) - 0.022_42).abs() < 1e-5);
        assert_eq!(binomial_sf(61, 60, 0.5), 0.0);
        // 50 trials at a 2% miss rate: P(X ≥ 5) = 0.0032 ≥ 1e-3 > P(X ≥ 6) = 0.000 48.
        assert_eq!(max_misses(50, 0.02, 1e-3), 5);
        assert_eq!(max_misses(10, 0.0, 1e-3), 0);
    }

    #[test]
    fn raw_state_stream_is_splitmix64() {
        // SplitMix64 from state 0: the reference values of Vigna's splitmix64.c.
        let mut r = Rng(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }
}
