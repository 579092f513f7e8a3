//! The demo's plates: the paper's section 7 laboratory set in simulation (Table 1's
//! training plates, Table 2's test plate), and the scene file of each.

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
}

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

/// The scene file of one demo plate (see docs/SCENE.md).
pub fn scene_text(p: &DemoPlate, seed: u64) -> String {
    format!(
        r#"# polarid demo: {label} ({target}), the paper's section 7 in simulation.
# Re-run it alone with: polarid simulate scene.toml -o DIR
name = "{target}"
width = {SIDE}
height = {SIDE}
theta_r_deg = {tr:.1}
phi_deg = 180.0
theta_i_deg = {{ start = {i0:.1}, stop = {i1:.1}, step = 5.0 }}
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

[[plate]]
name = "{target}"
class = "{class}"
n = {n}
k = {k}
sigma = {sigma}
rect = [0, 0, {SIDE}, {SIDE}]
region = [16, 16, 96, 96]
"#,
        label = p.label,
        target = p.target,
        class = p.class,
        tr = p.theta_r,
        i0 = p.theta_i.0,
        i1 = p.theta_i.1,
        n = p.n,
        k = p.k,
        sigma = p.sigma,
    )
}
