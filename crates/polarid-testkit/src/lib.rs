//! Helpers shared by polarid's integration tests: a dev-dependency of every crate, never
//! a dependency of the product.
//!
//! - [`Rng`]: a small deterministic generator (SplitMix64 with Box–Muller normal
//!   deviates), so that the tests need no random-number dependency and their streams
//!   stay the same across versions of `rand`;
//! - [`full`] and [`seeds`]: the size of the statistical studies (quick by default, full
//!   size with `POLARID_FULL=1`);
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

/// Writes `msg` on the terminal even while the test harness captures the output of
/// passing tests (it captures `print!`/`eprint!`, not direct writes to stderr).
pub fn note(msg: &str) {
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{msg}");
}

/// `note!("...", args)`: [`note`] with `format!` arguments, prefixed with the module of
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
    fn raw_state_stream_is_splitmix64() {
        // SplitMix64 from state 0: the reference values of Vigna's splitmix64.c.
        let mut r = Rng(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }
}
