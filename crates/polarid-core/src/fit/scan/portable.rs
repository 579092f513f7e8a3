//! The grid scan in plain Rust (any CPU): 32 nodes at a time in an array the compiler
//! may vectorise, separate multiply and add.

use super::{BandMin, L, SCAN_BLOCK, Scan, reduce};
use crate::fit::simd::Portable;

impl Scan for Portable {
    /// One pixel at a time: without vector registers the four-pixel scan saves no
    /// memory traffic.
    const FOUR: bool = false;

    #[inline(always)]
    fn scan(
        self,
        curves: &[f32],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    ) {
        scan_portable::<false>(curves, base, y, w, band, bands)
    }

    #[inline(always)]
    fn scan4(
        self,
        curves: &[f32],
        base: &[f32],
        ny: [&[f32]; 4],
        band: usize,
        bands: [&mut [BandMin]; 4],
    ) {
        for (y, b) in ny.into_iter().zip(bands) {
            scan_portable::<true>(curves, base, y, None, band, b);
        }
    }

    #[inline(always)]
    fn scan_rows(
        self,
        rows: &[&[f32]],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    ) {
        scan_rows_portable(rows, base, y, w, band, bands)
    }
}

/// [`Scan::scan_rows`] in plain Rust (separate multiply and add).
#[inline(always)]
fn scan_rows_portable(
    rows: &[&[f32]],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    const BL: usize = 32;
    let gp = base.len();
    let mut m = [f32::INFINITY; L];
    let mut ix = [u32::MAX; L];
    for b in 0..gp / SCAN_BLOCK {
        for h in 0..SCAN_BLOCK / BL {
            let g0 = b * SCAN_BLOCK + h * BL;
            let mut a = [0f32; BL];
            a.copy_from_slice(&base[g0..g0 + BL]);
            for (t, row) in rows.iter().enumerate() {
                let row = &row[g0..g0 + BL];
                let yt = y[t];
                let wt = w.map_or(1.0, |w| w[t]);
                for l in 0..BL {
                    let d = row[l] - yt;
                    let wd = if w.is_some() { wt * d } else { d };
                    a[l] += wd * d;
                }
            }
            for (l, &v) in a.iter().enumerate() {
                if v < m[l % L] {
                    m[l % L] = v;
                    ix[l % L] = (g0 + l) as u32;
                }
            }
        }
        if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == gp / SCAN_BLOCK {
            bands[b * SCAN_BLOCK / band] = reduce(&m, &ix);
            m = [f32::INFINITY; L];
            ix = [u32::MAX; L];
        }
    }
}

/// Scan of one pixel (see the module documentation of `scan`). `bands` receives one
/// [`BandMin`] per band. `NEGATED`: `y` holds the measurements negated (as the
/// four-pixel scans take them).
#[inline(always)]
fn scan_portable<const NEGATED: bool>(
    curves: &[f32],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    const BL: usize = 32;
    let t_len = y.len();
    let gp = base.len();
    let mut m = [f32::INFINITY; L];
    let mut ix = [u32::MAX; L];
    for b in 0..gp / SCAN_BLOCK {
        let blk = &curves[b * SCAN_BLOCK * t_len..(b + 1) * SCAN_BLOCK * t_len];
        for h in 0..SCAN_BLOCK / BL {
            let o = h * BL;
            let g0 = b * SCAN_BLOCK + o;
            let mut a = [0f32; BL];
            a.copy_from_slice(&base[g0..g0 + BL]);
            for t in 0..t_len {
                let row = &blk[t * SCAN_BLOCK + o..t * SCAN_BLOCK + o + BL];
                let yt = if NEGATED { -y[t] } else { y[t] };
                match w {
                    Some(w) => {
                        let wt = w[t];
                        for l in 0..BL {
                            let d = row[l] - yt;
                            let wd = wt * d;
                            a[l] += wd * d;
                        }
                    }
                    None => {
                        let ny = -yt;
                        for l in 0..BL {
                            a[l] += row[l] * ny;
                        }
                    }
                }
            }
            for (l, &v) in a.iter().enumerate() {
                if v < m[l % L] {
                    m[l % L] = v;
                    ix[l % L] = (g0 + l) as u32;
                }
            }
        }
        if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == gp / SCAN_BLOCK {
            bands[b * SCAN_BLOCK / band] = reduce(&m, &ix);
            m = [f32::INFINITY; L];
            ix = [u32::MAX; L];
        }
    }
}
