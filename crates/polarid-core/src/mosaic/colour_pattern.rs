//! The pattern of a colour polarization mosaic: a 2×2 polarizer [`Pattern`] under each
//! block of a 2×2 colour pattern of blocks (a 4×4 period).

use super::Pattern;
use crate::error::{CoreError, Result};

/// A colour polarization mosaic pattern: the 2×2 polarizer pattern of every block and
/// the colour of each of the four 2×2 blocks of the 4×4 period, block-row by block-row
/// (Sony IMX250MYR: polarizers `90,45,135,0`, colours `RGGB` — blocks `R G / G B`).
///
/// Raw pixel `(y, x)` lies in block `(⌊(y mod 4)/2⌋, ⌊(x mod 4)/2⌋)` under the polarizer
/// at cell `(y mod 2, x mod 2)` of the polarizer pattern. Colours are ASCII letters
/// (stored upper case); the distinct letters, in order of first appearance, are the
/// pattern's *bands* ([`ColourPattern::bands`]), numbered from 0.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourPattern {
    polar: Pattern,
    letters: [char; 4],
    bands: Vec<char>,
    /// Band index of each block (row-major).
    block_band: [usize; 4],
}

impl ColourPattern {
    /// Validate a colour pattern: exactly four ASCII letters (case-insensitive), the
    /// colour of each 2×2 polarizer block, block-row by block-row.
    ///
    /// Errors: [`CoreError::InvalidName`] (`what = "colour pattern"`) naming `color`.
    pub fn new(polar: Pattern, color: &str) -> Result<Self> {
        let err = |reason: &str| CoreError::InvalidName {
            what: "colour pattern",
            name: color.to_string(),
            reason: reason.to_string(),
        };
        let chars: Vec<char> = color.chars().collect();
        if chars.len() != 4 {
            return Err(err(
                "expected four colour letters, one per 2x2 polarizer block of the 4x4 \
                 period, block-row by block-row (e.g. RGGB)",
            ));
        }
        let mut letters = ['?'; 4];
        let mut bands: Vec<char> = Vec::new();
        let mut block_band = [0usize; 4];
        for (i, &c) in chars.iter().enumerate() {
            if !c.is_ascii_alphabetic() {
                return Err(err("colours must be ASCII letters (e.g. R, G, B)"));
            }
            let c = c.to_ascii_uppercase();
            letters[i] = c;
            block_band[i] = match bands.iter().position(|&b| b == c) {
                Some(p) => p,
                None => {
                    bands.push(c);
                    bands.len() - 1
                }
            };
        }
        Ok(Self {
            polar,
            letters,
            bands,
            block_band,
        })
    }

    /// Sony IMX250MYR: polarizers `90,45,135,0` under colours `RGGB`.
    pub fn imx250myr() -> Self {
        Self {
            polar: Pattern::imx250mzr(),
            letters: ['R', 'G', 'G', 'B'],
            bands: vec!['R', 'G', 'B'],
            block_band: [0, 1, 1, 2],
        }
    }

    /// The polarizer pattern of every block.
    pub fn polar(&self) -> &Pattern {
        &self.polar
    }

    /// The four colour letters, block-row by block-row (upper case), e.g. `"RGGB"`.
    pub fn color(&self) -> String {
        self.letters.iter().collect()
    }

    /// The distinct colours in order of first appearance: band `b` is `bands()[b]`.
    pub fn bands(&self) -> &[char] {
        &self.bands
    }

    /// The band index of block `block` (0..4, row-major in the 4×4 period).
    pub fn block_band(&self, block: usize) -> usize {
        self.block_band[block & 3]
    }

    /// `(band, k)` of raw pixel `(y, x)`: its band index and polarizer `k × 45°`.
    pub fn channel_at(&self, y: usize, x: usize) -> (usize, usize) {
        let block = ((y % 4) / 2) * 2 + (x % 4) / 2;
        let cell = (y % 2) * 2 + x % 2;
        // ok: `pos` is a permutation of 0..4, so the cell is found.
        let k = self.polar.pos.iter().position(|&p| p == cell).unwrap_or(0);
        (self.block_band[block], k)
    }

    /// The lattices (`4·ρ + χ`, `ρ = y mod 4`, `χ = x mod 4`) of band `band` under the
    /// polarizer `k × 45°`, in increasing order.
    pub(super) fn lattices(&self, band: usize, k: usize) -> Vec<usize> {
        (0..16)
            .filter(|&l| self.channel_at(l / 4, l % 4) == (band, k & 3))
            .collect()
    }
}

impl Default for ColourPattern {
    fn default() -> Self {
        Self::imx250myr()
    }
}

/// The height of a `width`-wide colour mosaic of `len` pixels: whole rows, width and
/// height multiples of the 4×4 period and at least 4; else
/// [`CoreError::InvalidDimensions`].
pub(super) fn check_colour_mosaic(width: usize, len: usize) -> Result<usize> {
    let height = len.checked_div(width).unwrap_or(0);
    if width == 0 || len != width * height {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: format!("{len} pixels do not form whole rows"),
        });
    }
    if !width.is_multiple_of(4) || !height.is_multiple_of(4) || width < 4 || height < 4 {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: "a colour polarization mosaic has a 4x4 period: width and height must \
                     be non-zero multiples of 4"
                .into(),
        });
    }
    Ok(height)
}
