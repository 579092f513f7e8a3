//! PNG encoding of the RGB rasters that polarid draws (plots and the `stokes` views),
//! with the `png` crate: 8-bit RGB, fast deflate, adaptive filtering per scanline.

/// Encode `rgb` (`w × h × 3` bytes, rows top to bottom) as an 8-bit RGB PNG with fast
/// compression and adaptive filters.
pub fn encode_rgb8(rgb: &[u8], w: u32, h: u32) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::with_capacity(rgb.len() / 2);
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        enc.set_filter(png::Filter::Adaptive);
        let mut wr = enc.write_header()?;
        wr.write_image_data(rgb)?;
        wr.finish()?;
    }
    Ok(out)
}

/// Decode an 8-bit PNG into `(width, height, RGB bytes)` (grayscale and alpha are
/// expanded or dropped). For the tests of what polarid draws.
#[cfg(test)]
pub fn decode_rgb8(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec
        .read_info()
        .unwrap_or_else(|e| panic!("PNG does not decode: {e}"));
    let size = reader
        .output_buffer_size()
        .unwrap_or_else(|| panic!("PNG too large"));
    let mut buf = vec![0u8; size];
    let info = reader
        .next_frame(&mut buf)
        .unwrap_or_else(|e| panic!("PNG does not decode: {e}"));
    buf.truncate(info.buffer_size());
    let (w, h) = (info.width, info.height);
    let rgb = match info.color_type {
        png::ColorType::Rgb => buf,
        png::ColorType::Rgba => buf
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect(),
        png::ColorType::Grayscale => buf.iter().flat_map(|&g| [g, g, g]).collect(),
        png::ColorType::GrayscaleAlpha => buf
            .chunks_exact(2)
            .flat_map(|p| [p[0], p[0], p[0]])
            .collect(),
        png::ColorType::Indexed => panic!("indexed PNG after EXPAND"),
    };
    (w, h, rgb)
}
