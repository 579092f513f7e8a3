//! Throughput of the colour polarization kernel on a 2048×2448 uint16 IMX250MYR-style
//! mosaic (polarizers 90,45,135,0 under RGGB blocks): raw → per-band S0, S1, S2, DoLP and
//! AoLP (bilinear, full resolution) and the super-pixel method, into caller-owned
//! buffers allocated once. Prints one JSON line (best of `--repeats`, default 7). Run:
//! `cargo run --release -p polarid-core --example colour_throughput [-- --repeats N]
//! [--raw FILE --width W --height H]` (`FILE`: little-endian uint16, row-major).

use std::time::Instant;

use polarid_core::mosaic::{ColourMethod, ColourPattern, DofpOutputs, colour_polar};
use polarid_core::stokes::PixelRules;

fn best_of<F: FnMut()>(n: usize, mut f: F) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..n {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let repeats: usize = args
        .iter()
        .position(|a| a == "--repeats")
        .and_then(|i| args.get(i + 1))
        .map_or(7, |v| v.parse().unwrap_or(7));
    let opt = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let h: usize = opt("--height").map_or(2048, |v| v.parse().unwrap_or(2048));
    let w: usize = opt("--width").map_or(2448, |v| v.parse().unwrap_or(2448));
    // --raw FILE: the frame as little-endian uint16, row-major (scripts/bench/colour.py)
    let raw: Vec<u16> = match opt("--raw") {
        Some(path) => {
            let bytes = std::fs::read(&path).unwrap_or_default();
            if bytes.len() != 2 * w * h {
                eprintln!("colour_throughput: {path}: expected {} bytes", 2 * w * h);
                std::process::exit(2);
            }
            bytes
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect()
        }
        None => {
            let mut s = 12345u64;
            (0..w * h)
                .map(|_| {
                    s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                    (200 + (s >> 40) % 3000) as u16
                })
                .collect()
        }
    };
    let p = ColourPattern::imx250myr();
    let rules = PixelRules {
        saturation: 4095.0,
        ..Default::default()
    };
    let mut json = Vec::new();
    for (name, method) in [
        ("bilinear", ColourMethod::Bilinear),
        ("superpixel", ColourMethod::Superpixel),
    ] {
        let (ow, oh) = method.output_size(w, h);
        let mut bufs: Vec<[Vec<f32>; 5]> = (0..3)
            .map(|_| std::array::from_fn(|_| vec![0f32; ow * oh]))
            .collect();
        let t = best_of(repeats, || {
            let outs = bufs
                .iter_mut()
                .map(|[s0, s1, s2, d, a]| DofpOutputs {
                    s0: Some(s0),
                    s1: Some(s1),
                    s2: Some(s2),
                    mask: None,
                    dolp: Some(d),
                    aolp: Some(a),
                })
                .collect();
            colour_polar(&raw, w, &p, method, &rules, outs).expect("valid sizes");
        });
        let mpix = (w * h) as f64 / 1e6 / t;
        println!(
            "{name}: raw -> 3 bands x (S0,S1,S2,DoLP,AoLP): {:.1} ms, {mpix:.0} Mpixel/s",
            t * 1e3
        );
        json.push(format!(
            "\"colour_{name}\": {{\"best_s\": {t:.5}, \"mpix_per_s\": {mpix:.1}}}"
        ));
    }
    println!("{{{}}}", json.join(", "));
}
