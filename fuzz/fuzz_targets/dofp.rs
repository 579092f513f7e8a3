//! The DoFP path on arbitrary small frames and patterns: pattern validation,
//! bilinear demosaicing, super-pixel and bilinear Stokes, DoLP/AoLP and region
//! statistics; and the rotating-polarizer solver on arbitrary angle sets. Every call
//! must return `Ok` or `Err`, never panic, and accepted outputs must be in range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polarid_core::mosaic::{self, Pattern};
use polarid_core::region::{Rect, Sampling, region_stats};
use polarid_core::stokes::{self, PixelRules, StokesSolver};

struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }
    /// An angle: mostly the multiples of 45 (and their aliases), sometimes anything.
    fn angle(&mut self) -> f64 {
        match self.u8() {
            b @ 0..=199 => f64::from(b % 8) * 45.0 - 90.0,
            200..=249 => f64::from(self.u16()) / 100.0 - 300.0,
            250 => f64::NAN,
            251 => f64::INFINITY,
            _ => f64::from(f32::from_bits(u32::from(self.u16()) << 16)),
        }
    }
    fn value(&mut self) -> f32 {
        match self.u8() {
            0..=239 => f32::from(self.u16()),
            240..=247 => f32::from_bits(u32::from(self.u16()) << 16 | u32::from(self.u16())),
            248 => f32::NAN,
            249 => f32::INFINITY,
            _ => -f32::from(self.u8()),
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let width = usize::from(b.u8() % 17);
    let len = usize::from(b.u8()) % 290;
    let pattern_angles: Vec<f64> = (0..(b.u8() % 6)).map(|_| b.angle()).collect();
    let rules = PixelRules {
        dark_level: f32::from(b.u8()),
        saturation: match b.u8() {
            0 => f32::INFINITY,
            1 => f32::NAN,
            s => f32::from(s) * 300.0,
        },
        min_s0: f32::from(b.u8() % 4),
    };
    let round = b.u8() & 1 == 1;
    let rect = Rect {
        x: usize::from(b.u8() % 20),
        y: usize::from(b.u8() % 20),
        width: usize::from(b.u8() % 20),
        height: usize::from(b.u8() % 20),
    };
    let raw: Vec<f32> = (0..len).map(|_| b.value()).collect();
    let raw16: Vec<u16> = raw.iter().map(|&v| v.clamp(0.0, 65535.0) as u16).collect();

    if let Ok(pattern) = Pattern::new(&pattern_angles) {
        let mut angles = pattern.angles_deg();
        angles.sort_by(f64::total_cmp);
        assert_eq!(angles, [0.0, 45.0, 90.0, 135.0]);
        let n = len;
        let (mut s0, mut s1, mut s2, mut mask) =
            (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
        if let Ok(c) = mosaic::bilinear_stokes(
            &raw, width, &pattern, &rules, round, &mut s0, &mut s1, &mut s2, &mut mask,
        ) {
            assert_eq!(c.valid + c.saturated + c.dark + c.invalid, n as u64);
            let (mut d, mut a) = (vec![0f32; n], vec![0f32; n]);
            if stokes::dolp_aolp(width, &s0, &s1, &s2, Some(&mask), &mut d, &mut a).is_ok() {
                assert!(d.iter().all(|v| v.is_nan() || (0.0..=1.0).contains(v)));
                assert!(a.iter().all(|v| v.is_nan() || (0.0..180.0).contains(v)));
            }
            for sampling in [Sampling::BilinearDofp, Sampling::Independent] {
                if let Ok(st) = region_stats(width, &s0, &s1, &s2, &mask, rect, sampling) {
                    assert!(st.dolp.is_nan() || (0.0..=1.0).contains(&st.dolp));
                }
            }
        }
        let _ = mosaic::bilinear_stokes(
            &raw16, width, &pattern, &rules, round, &mut s0, &mut s1, &mut s2, &mut mask,
        );
        let (mut c0, mut c1, mut c2, mut c3) =
            (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        let _ = mosaic::demosaic_bilinear(
            &raw16,
            width,
            &pattern,
            round,
            [&mut c0, &mut c1, &mut c2, &mut c3],
        );
        let q = n / 4;
        let (mut s0, mut s1, mut s2, mut mask) =
            (vec![0f32; q], vec![0f32; q], vec![0f32; q], vec![0u8; q]);
        if let Ok(c) = mosaic::superpixel_stokes(
            &raw, width, &pattern, &rules, &mut s0, &mut s1, &mut s2, &mut mask,
        ) {
            assert_eq!(c.valid + c.saturated + c.dark + c.invalid, q as u64);
        }
    }

    // Rotating polarizer: the same bytes as an angle set and frames.
    if let Ok(solver) = StokesSolver::from_degrees(&pattern_angles) {
        let k = pattern_angles.len();
        let per = if k == 0 { 0 } else { len / k };
        let frames: Vec<&[f32]> = (0..k).map(|i| &raw[i * per..(i + 1) * per]).collect();
        let (mut s0, mut s1, mut s2, mut mask) =
            (vec![0f32; per], vec![0f32; per], vec![0f32; per], vec![0u8; per]);
        let _ = solver.compute(&frames, width, &rules, &mut s0, &mut s1, &mut s2, &mut mask);
    }
});
