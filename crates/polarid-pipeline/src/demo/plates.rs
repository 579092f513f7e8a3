//! The demo's plates: the paper's section 7 laboratory set in simulation (Table 1's
//! training plates, Table 2's test plate), and the scene file of each.
//!
//! **Real plates are not their tabulated index.** Each plate carries its material's
//! native surface layer (field notes; Al under 2–5 nm of Al₂O₃, n ≈ 1.65; Cu under
//! 0.5–3 nm of Cu₂O, 2.9 + 0.1i at 650 nm; a painted surface under up to 1 nm of adsorbed
//! contamination, n ≈ 1.5), of its own thickness, so that two plates of one material
//! differ by their layers. The scenes have no layers, so each plate is rendered with the
//! index a single-interface fit sees on the layered surface at its own β
//! ([`super::colour::apparent_index_at`]).

/// One simulated plate of the demo.
#[derive(Debug, Clone, Copy)]
pub struct DemoPlate {
    /// Target name.
    pub target: &'static str,
    /// Material (class).
    pub class: &'static str,
    /// Display name.
    pub label: &'static str,
    /// Real part of the index of refraction (paper Table 1 references).
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
    /// Roughness σ.
    pub sigma: f64,
    /// Camera zenith, degrees.
    pub theta_r: f64,
    /// Source zeniths: first, last (5° steps), degrees.
    pub theta_i: (f64, f64),
    /// Training plate (else test).
    pub training: bool,
    /// Its native surface layer: index `(n, k)` and thickness, nm.
    pub layer: ((f64, f64), f64),
}

/// The native layer of each class: index `(n, k)` at 650 nm and the range of thicknesses
/// found on real surfaces, nm (field notes, "Surfaces as they are found").
pub fn native_layer(class: &str) -> ((f64, f64), (f64, f64)) {
    match class {
        "aluminum" => ((1.65, 0.0), (2.0, 5.0)),
        "copper" => ((2.9, 0.1), (0.5, 3.0)),
        _ => ((1.5, 0.0), (0.0, 1.0)),
    }
}

impl DemoPlate {
    /// The source zeniths, degrees (5° steps).
    pub fn theta_is(&self) -> Vec<f64> {
        let steps = ((self.theta_i.1 - self.theta_i.0) / 5.0).round() as usize;
        (0..=steps)
            .map(|i| self.theta_i.0 + 5.0 * i as f64)
            .collect()
    }

    /// The index a single-interface fit sees on the plate (its bulk index under its
    /// layer) at its nominal geometry, at 650 nm.
    pub fn seen_index(&self) -> (f64, f64) {
        let betas: Vec<f64> = self
            .theta_is()
            .iter()
            .map(|t| (0.5 * (t + self.theta_r)).to_radians())
            .collect();
        super::colour::apparent_index_at(
            (self.n, self.k),
            self.layer.0,
            self.layer.1,
            WAVELENGTH_NM,
            &betas,
        )
    }
}

/// The demo's wavelength, nm.
pub const WAVELENGTH_NM: f64 = 650.0;

/// The five plates: three training plates (paper Table 1) and the test aluminum plate
/// seen from θr = 60° and 50° (Table 2).
pub const PLATES: [DemoPlate; 5] = [
    DemoPlate {
        target: "green_paint",
        class: "green_paint",
        label: "Green paint",
        n: 1.39,
        k: 0.34,
        sigma: 0.25,
        theta_r: 60.0,
        theta_i: (40.0, 80.0),
        training: true,
        layer: ((1.5, 0.0), 0.4),
    },
    DemoPlate {
        target: "aluminum",
        class: "aluminum",
        label: "Aluminum",
        n: 1.24,
        k: 6.60,
        sigma: 0.20,
        theta_r: 60.0,
        theta_i: (35.0, 80.0),
        training: true,
        layer: ((1.65, 0.0), 3.0),
    },
    DemoPlate {
        target: "copper",
        class: "copper",
        label: "Copper",
        n: 0.40,
        k: 2.95,
        sigma: 0.15,
        theta_r: 60.0,
        theta_i: (35.0, 70.0),
        training: true,
        layer: ((2.9, 0.1), 1.5),
    },
    DemoPlate {
        target: "test_plate_60",
        class: "aluminum",
        label: "Test plate",
        n: 1.24,
        k: 6.60,
        sigma: 0.30,
        theta_r: 60.0,
        theta_i: (35.0, 80.0),
        training: false,
        layer: ((1.65, 0.0), 4.2),
    },
    DemoPlate {
        target: "test_plate_50",
        class: "aluminum",
        label: "Test plate",
        n: 1.24,
        k: 6.60,
        sigma: 0.30,
        theta_r: 50.0,
        theta_i: (35.0, 80.0),
        training: false,
        layer: ((1.65, 0.0), 4.2),
    },
];

/// The paper's own estimates (Tables 1 and 2), for comparison: target → (n̂, k̂).
pub fn paper_estimate(target: &str) -> Option<(f64, f64)> {
    match target {
        "green_paint" => Some((1.47, 0.47)),
        "aluminum" => Some((1.64, 4.56)),
        "copper" => Some((0.54, 3.19)),
        "test_plate_60" => Some((1.37, 3.97)),
        "test_plate_50" => Some((1.60, 4.34)),
        _ => None,
    }
}

/// Frame side, pixels (one plate per frame; the measured region is the central 96²).
pub const SIDE: usize = 128;

/// The scene file of one demo plate (see docs/SCENE.md): rendered with the index it
/// shows under its layer ([`DemoPlate::seen_index`]) at its nominal angles.
pub fn scene_text(p: &DemoPlate, seed: u64) -> String {
    scene_text_at(p, p.target, seed, p.seen_index(), p.theta_r, &p.theta_is())
}

/// [`scene_text`] for the plate named `target`, with the index `seen` and the true
/// camera and source zeniths (degrees; a bench whose angles are off renders at the true
/// ones).
pub fn scene_text_at(
    p: &DemoPlate,
    target: &str,
    seed: u64,
    seen: (f64, f64),
    theta_r: f64,
    theta_i: &[f64],
) -> String {
    let angle = |t: f64| {
        if (t * 10.0 - (t * 10.0).round()).abs() < 1e-9 {
            format!("{t:.1}")
        } else {
            format!("{t:.4}")
        }
    };
    let nominal = p.theta_is();
    let ti = if theta_i == nominal.as_slice() {
        format!(
            "{{ start = {:.1}, stop = {:.1}, step = 5.0 }}",
            p.theta_i.0, p.theta_i.1
        )
    } else {
        let v: Vec<String> = theta_i.iter().map(|&t| angle(t)).collect();
        format!("[{}]", v.join(", "))
    };
    let tr = angle(theta_r);
    format!(
        r#"# polarid demo: {label} ({target}), the paper's section 7 in simulation.
# Re-run it alone with: polarid simulate scene.toml -o DIR
name = "{target}"
width = {SIDE}
height = {SIDE}
theta_r_deg = {tr}
phi_deg = 180.0
theta_i_deg = {ti}
wavelength_nm = 650.0
seed = {seed}
format = "png"

[sensor]                  # a 12-bit machine-vision camera
bit_depth = 12
full_well_e = 10500.0
read_noise_e = 2.5
dark_level_dn = 64.0
shot_noise = true

[exposure]                # brightest plate pixel at 70 % of full scale
mode = "auto"
fraction = 0.7

[capture]
kind = "frames"
angles_deg = [0, 45, 90, 135]

# {label}: bulk {n0} + {k0}i under {ln:.2} nm of a layer of index {lfn} + {lfk}i: rendered
# with the index a single-interface fit sees on it.
[[plate]]
name = "{target}"
class = "{class}"
n = {n:.6}
k = {k:.6}
sigma = {sigma}
rect = [0, 0, {SIDE}, {SIDE}]
region = [16, 16, 96, 96]
"#,
        label = p.label,
        class = p.class,
        tr = tr,
        ti = ti,
        n0 = p.n,
        k0 = p.k,
        ln = p.layer.1,
        lfn = p.layer.0.0,
        lfk = p.layer.0.1,
        n = seen.0,
        k = seen.1,
        sigma = p.sigma,
    )
}
