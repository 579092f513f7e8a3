//! Write a large capture set for measuring `polarid map`'s speed and peak memory:
//! 10 captures (θi = 35…80°, θr = 60°) of four 0/45/90/135° uint16 TIFF frames of
//! 2048×2448 pixels (four plates — green paint, aluminum, copper, rough aluminum — on
//! a dark background, 12-bit sensor with shot and read noise), and `manifest.toml`.
//!
//! Run: `cargo run --release -p polarid-cli --example bigmap_frames -- DIR [HEIGHT WIDTH]`
//! (keep DIR outside the repository), then e.g.
//! `polarid measure DIR/manifest.toml -o m.csv && polarid fit m.csv -o f.csv &&
//! polarid train f.csv -o model.json && /usr/bin/time -v polarid map DIR/manifest.toml --model model.json -o OUT`.

use std::path::PathBuf;

use polarid_core::simulate::{
    Analyzer, PlateOptics, Sensor, UniformRect, plate_radiance, render_frame,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut a = std::env::args().skip(1);
    let dir = PathBuf::from(a.next().ok_or("usage: bigmap_frames DIR [HEIGHT WIDTH]")?);
    let h: usize = a.next().map_or(Ok(2048), |v| v.parse())?;
    let w: usize = a.next().map_or(Ok(2448), |v| v.parse())?;
    std::fs::create_dir_all(&dir)?;
    let sensor = Sensor {
        bit_depth: 12,
        full_well_e: 32_000.0,
        read_noise_e: 16.0,
        dark_level_dn: 64.0,
        shot_noise: true,
    };
    let (pw, ph) = (w / 2 - w / 8, h / 2 - h / 8);
    let plates = [
        (
            "green_paint",
            "green_paint",
            1.39,
            0.34,
            0.20,
            w / 16,
            h / 16,
        ),
        (
            "aluminum",
            "aluminum",
            1.24,
            6.60,
            0.20,
            w / 2 + w / 16,
            h / 16,
        ),
        ("copper", "copper", 0.40, 2.95, 0.15, w / 16, h / 2 + h / 16),
        (
            "aluminum_rough",
            "aluminum",
            1.24,
            6.60,
            0.30,
            w / 2 + w / 16,
            h / 2 + h / 16,
        ),
    ];
    let mut text = String::from(
        "theta_r_deg = 60.0\nphi_deg = 180.0\ndark_level = 64.0\nsaturation = 4095.0\n",
    );
    for (name, class, _, _, _, x, y) in plates {
        text += &format!(
            "\n[[region]]\nname = \"{name}\"\nrect = [{}, {}, 100, 100]\nclass = \"{class}\"\n",
            x + pw / 2 - 50,
            y + ph / 2 - 50
        );
    }
    let theta_r = 60f64.to_radians();
    let mut frame = vec![0u16; w * h];
    for (ci, ti) in (0..10).map(|i| 35.0 + 5.0 * i as f64).enumerate() {
        let rects: Vec<UniformRect> = plates
            .iter()
            .map(|&(_, _, n, k, sigma, x, y)| {
                let o = PlateOptics {
                    n,
                    k,
                    sigma,
                    rho_d: 0.0,
                };
                let s = plate_radiance(&o, ti.to_radians(), theta_r, std::f64::consts::PI)?;
                Ok(UniformRect {
                    x,
                    y,
                    width: pw,
                    height: ph,
                    stokes: s,
                })
            })
            .collect::<Result<_, polarid_core::CoreError>>()?;
        let brightest = rects
            .iter()
            .map(|r| 0.5 * (r.stokes[0] + r.stokes[1].hypot(r.stokes[2])))
            .fold(0.0, f64::max);
        let epu = 0.7 * sensor.full_well_e / brightest;
        text += &format!("\n[[capture]]\ntheta_i_deg = {ti}\nframes = [\n");
        for ang in [0.0f64, 45.0, 90.0, 135.0] {
            let name = format!("i{ti}_{ang}.tif");
            render_frame(
                w,
                h,
                &rects,
                [0.0; 3],
                Analyzer::Uniform(ang.to_radians()),
                &sensor,
                epu,
                100 * ci as u64 + ang as u64,
                &mut frame,
            )?;
            polarid_io::image::write_gray16(&dir.join(&name), true, w, h, &frame)?;
            text += &format!("  {{ angle_deg = {ang}, file = \"{name}\" }},\n");
        }
        text += "]\n";
        eprintln!("capture {ti} written");
    }
    std::fs::write(dir.join("manifest.toml"), text)?;
    Ok(())
}
