//! Tests of the report layouts (the sample report draws its figures with
//! [`crate::render::plots`]).

use super::html::html_escape;
use super::markdown::md_escape;
use super::*;
use crate::render::base64::encode as base64_encode;
use crate::render::plots::{self, PlotSize};

#[test]
fn escapes() {
    assert_eq!(
        html_escape(r#"<a href="x">&'</a>"#),
        "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;"
    );
    assert_eq!(md_escape("a|b *c* <d>\n_e_"), r"a\|b \*c\* \<d\> \_e\_");
}

const EVIL: &str = "<script>alert('x')</script> & \"q\" | *b*";

/// A report filled with synthetic data in the shape of the paper's Tables 1 and 2.
pub(crate) fn sample_report(evil: bool) -> (Report, Vec<(String, crate::render::Rendered)>) {
    let train = [
        ("green paint", 1.39, 0.34, 1.47, 0.47, 40.0, 80.0),
        ("aluminum", 1.24, 6.60, 1.64, 4.56, 35.0, 80.0),
        ("copper", 0.40, 2.95, 0.54, 3.19, 35.0, 70.0),
    ];
    let tests = [
        ("test θr=60°", 60.0, 1.37, 3.97),
        ("test θr=50°", 50.0, 1.60, 4.34),
    ];
    let size = PlotSize::REPORT;
    let mut series = Vec::new();
    let mut geometry = Vec::new();
    for &(name, _, _, nh, kh, i0, i1) in &train {
        let pts: Vec<plots::DolpPoint> = (0..=((i1 - i0) / 5.0) as usize)
            .map(|j| {
                let ti = i0 + 5.0 * j as f64;
                let beta = 0.5 * (ti + 60.0);
                plots::DolpPoint {
                    beta_deg: beta,
                    dolp: polarid_core::dop::dop(nh, kh, beta.to_radians())
                        + 0.006 * (j as f64 * 2.1).sin(),
                    dolp_se: Some(0.008),
                }
            })
            .collect();
        geometry.push(GeometryRow {
            target: name.into(),
            class: Some(name.into()),
            theta_r_deg: 60.0,
            theta_i_deg: (i0, i1),
            phi_deg: 180.0,
            beta_deg: (0.5 * (i0 + 60.0), 0.5 * (i1 + 60.0)),
            captures: pts.len(),
        });
        series.push(plots::DolpSeries {
            label: name.into(),
            points: pts,
            curve: plots::eq9_curve(nh, kh, 45.0, 72.0, 120),
            curve_label: Some(format!("fit n = {nh:.2}, k = {kh:.2}")),
        });
    }
    let dolp =
        plots::dolp_vs_beta("DoLP against β, training plates (θr = 60°)", &series, size).unwrap();
    let protos: Vec<plots::Prototype> = train
        .iter()
        .map(|&(class, _, _, n, k, ..)| plots::Prototype {
            class: class.into(),
            n,
            k,
        })
        .collect();
    let ests: Vec<plots::NkEstimate> = tests
        .iter()
        .map(|t| plots::NkEstimate {
            label: t.0.into(),
            n: t.2,
            k: t.3,
            n_se: 0.09,
            k_se: 0.35,
            corr: 0.7,
            predicted: Some("aluminum".into()),
            answer: None,
            regions: Vec::new(),
        })
        .collect();
    let nk = plots::nk_plane("Test estimates in the (n, k) plane", &protos, &ests, size).unwrap();
    let (w, h) = (96usize, 64usize);
    let classes: Vec<u16> = (0..w * h)
        .map(|i| match (i % w, i / w) {
            (x, y) if (10..40).contains(&x) && (8..56).contains(&y) => 1,
            (x, y) if (50..86).contains(&x) && (8..30).contains(&y) => 2,
            (x, y) if (50..86).contains(&x) && (34..56).contains(&y) => 3,
            _ => 0,
        })
        .collect();
    let names: Vec<String> = train.iter().map(|t| t.0.to_string()).collect();
    let cmap = plots::class_map("Material map", w, h, &classes, &names, size).unwrap();
    let dolp_img: Vec<f32> = (0..w * h)
        .map(|i| ((i % w) as f32 / w as f32) * 0.6 + ((i / w) as f32 / h as f32) * 0.2)
        .collect();
    let smap =
        plots::scalar_map("DoLP image, θi = 45°", w, h, &dolp_img, None, "DoLP", size).unwrap();

    let tag = if evil { EVIL } else { "" };
    let report = Report {
        title: format!("polarid demo: the paper's experiment in simulation{tag}"),
        summary: vec![format!(
            "Three training plates and one test plate, simulated from the pBRDF, measured \
             and fitted with eq. (9), then classified by nearest neighbour.{tag}"
        )],
        inputs: vec![InputItem {
            role: "manifest".into(),
            path: format!("captures/manifest{tag}.toml"),
            detail: "3 training plates, 2 test views, rotating polarizer 0/45/90/135°".into(),
        }],
        manifest: vec![
            ("wavelength".into(), "650 nm".into()),
            ("sensor".into(), format!("12 bit, full well 10000 e⁻{tag}")),
        ],
        geometry,
        references: train
            .iter()
            .map(|t| ReferenceRow {
                material: t.0.into(),
                n: t.1,
                k: t.2,
                source: "paper, Table 1".into(),
            })
            .collect(),
        estimates: train
            .iter()
            .map(|t| EstimateRow {
                target: t.0.into(),
                class: Some(t.0.into()),
                theta_r_deg: Some(60.0),
                n: t.3,
                n_se: 0.05,
                k: t.4,
                k_se: 0.2,
                nk_corr: 0.8,
                rms_residual: 0.0042,
                measurements: 9,
                status: polarid_core::FitStatus::Ok,
            })
            .chain(tests.iter().map(|t| EstimateRow {
                target: format!("{}{tag}", t.0),
                class: Some("aluminum".into()),
                theta_r_deg: Some(t.1),
                n: t.2,
                n_se: 0.09,
                k: t.3,
                k_se: 0.35,
                nk_corr: 0.7,
                rms_residual: 0.005,
                measurements: 10,
                status: polarid_core::FitStatus::Ok,
            }))
            .collect(),
        classification: tests
            .iter()
            .map(|t| ClassificationRow {
                target: format!("{}{tag}", t.0),
                truth: Some("aluminum".into()),
                predicted: "aluminum".into(),
                distance: 0.62,
                runner_up: Some("copper".into()),
                runner_up_distance: Some(1.27),
                status: "ok".into(),
                ..Default::default()
            })
            .collect(),
        tables: vec![],
        figures: vec![
            Figure::from_rendered(
                "DoLP against β",
                "Measured DoLP (points, ±1 SE bars) and the fitted eq. (9) curves.",
                &dolp,
                "dolp_beta.png",
                Some("dolp_beta.svg".into()),
            ),
            Figure::from_rendered(
                "The (n, k) plane",
                format!(
                    "Prototypes, test estimates with 1-σ ellipses, and the \
                     nearest-neighbour regions.{tag}"
                ),
                &nk,
                "nk_plane.png",
                Some("nk_plane.svg".into()),
            ),
            Figure::from_rendered(
                "Material map",
                "Class of each pixel.",
                &cmap,
                "class_map.png",
                None,
            ),
            Figure::from_rendered(
                "DoLP image",
                "DoLP of one capture.",
                &smap,
                "dolp_map.png",
                None,
            ),
        ],
        generator: "polarid test suite".into(),
    };
    let plots = vec![
        ("dolp_beta".to_string(), dolp),
        ("nk_plane".to_string(), nk),
        ("class_map".to_string(), cmap),
        ("dolp_map".to_string(), smap),
    ];
    (report, plots)
}

#[test]
fn html_has_every_section_and_embedded_plots() {
    let (report, _) = sample_report(false);
    let html = report.to_html().unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    for (id, heading) in SECTIONS {
        assert!(
            html.contains(&format!("<section id=\"{id}\">")),
            "section {id}"
        );
        assert!(
            html.contains(&format!("<h2>{heading}</h2>")),
            "heading {heading}"
        );
    }
    assert_eq!(html.matches("<img src=\"data:image/png;base64,").count(), 4);
    // The embedded data is exactly the figure's PNG.
    let b64 = base64_encode(&report.figures[1].png);
    assert!(html.contains(&format!("data:image/png;base64,{b64}\"")));
    assert!(html.contains("width=\"1000\" height=\"640\""));
    // Tables carry the values.
    assert!(html.contains("<td>1.370 ± 0.090</td>"), "estimate with SE");
    assert!(html.contains("<td>0.650</td>"), "margin = 1.27 - 0.62");
    assert!(html.contains("<td>6.600</td>"), "reference k of aluminum");
    assert!(html.contains("S1 = I(0°) − I(90°)"));
    assert!(html.contains("P(n, k, β) = 2A sin²β cos β"));
    assert!(html.contains("exp(−tan²θ / (2σ²))"));
    assert!(html.contains("exit with 0 on success, 2 for bad input"));
    // Self-contained: nothing is fetched.
    assert!(!html.contains("http://") && !html.contains("https://"));
    assert!(!html.contains("<script"));
}

#[test]
fn user_strings_are_escaped() {
    let (report, _) = sample_report(true);
    let html = report.to_html().unwrap();
    assert!(!html.contains("<script"), "unescaped script tag");
    assert!(!html.contains("alert('x')"));
    assert!(html.contains("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;"));
    // Every tag in the document is one the report itself writes.
    let allowed = [
        "!DOCTYPE",
        "html",
        "head",
        "meta",
        "title",
        "style",
        "body",
        "main",
        "h1",
        "h2",
        "h3",
        "p",
        "nav",
        "ul",
        "li",
        "a",
        "section",
        "table",
        "caption",
        "thead",
        "tbody",
        "tr",
        "th",
        "td",
        "code",
        "dl",
        "dt",
        "dd",
        "figure",
        "img",
        "figcaption",
        "strong",
        "pre",
    ];
    for part in html.split('<').skip(1) {
        let name: String = part
            .trim_start_matches('/')
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '!')
            .collect();
        let name = if name.eq_ignore_ascii_case("!DOCTYPE") {
            "!DOCTYPE".into()
        } else {
            name
        };
        assert!(allowed.contains(&name.as_str()), "unexpected tag <{name}");
    }
    let md = report.to_markdown().unwrap();
    // Every '<' in the Markdown is escaped, or opens one of our link targets.
    for (i, _) in md.match_indices('<') {
        let before = &md[..i];
        assert!(
            before.ends_with('\\') || before.ends_with("]("),
            "unescaped '<' at {i}: {}",
            &md[i.saturating_sub(20)..(i + 20).min(md.len())]
        );
    }
    assert!(md.contains(r#"\<script\>alert('x')\</script\> \& "q" \| \*b\*"#));
}

#[test]
fn markdown_references_plot_files() {
    let dir = tempfile::tempdir().unwrap();
    let (report, plots) = sample_report(false);
    for (stem, r) in &plots {
        r.write(dir.path(), stem).unwrap();
    }
    let (html_path, md_path) = report.write(dir.path(), "report").unwrap();
    let md = std::fs::read_to_string(&md_path).unwrap();
    for heading in [
        "## Inputs",
        "## Geometry",
        "## Reference indices",
        "## Estimates",
        "## Classification",
        "## Plots",
        "## Conventions",
    ] {
        assert!(md.contains(heading), "{heading}");
    }
    for f in &report.figures {
        let link = format!("](<{}>)", f.png_file);
        assert!(md.contains(&link), "{link}");
        assert!(dir.path().join(&f.png_file).is_file());
    }
    assert!(md.contains("([SVG](<nk_plane.svg>))"));
    assert!(md.contains(
        "| test θr=60° | aluminum | aluminum | 0.620 | copper | 1.270 | 0.650 | yes | ok |"
    ));
    let html = std::fs::read_to_string(html_path).unwrap();
    assert_eq!(html, report.to_html().unwrap());
}

#[test]
fn empty_report_still_has_all_sections() {
    let r = Report::default();
    let html = r.to_html().unwrap();
    for (id, _) in SECTIONS {
        assert!(html.contains(&format!("<section id=\"{id}\">")), "{id}");
    }
    assert!(html.contains("None."));
    assert!(r.to_markdown().unwrap().contains("## Conventions"));
    let bad = Report {
        figures: vec![Figure {
            title: "x".into(),
            png: b"not a png".to_vec(),
            ..Figure::default()
        }],
        ..Report::default()
    };
    assert!(bad.to_html().unwrap_err().to_string().contains("not a PNG"));
}

/// The report opens in headless Chromium without errors and all its plots decode
/// (`scripts/check_report.sh`; skipped when Chromium is not installed, unless
/// `POLARID_REQUIRE_BROWSER=1`).
#[test]
fn report_renders_in_headless_browser() {
    let dir = tempfile::tempdir().unwrap();
    let (report, _) = sample_report(false);
    let (html, _) = report.write(dir.path(), "report").unwrap();
    let shot = dir.path().join("shot.png");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scripts/check_report.sh");
    let out = match std::process::Command::new("bash")
        .arg(script)
        .arg(&html)
        .arg(&shot)
        .output()
    {
        Ok(o) => o,
        Err(e) => {
            assert!(
                std::env::var("POLARID_REQUIRE_BROWSER").as_deref() != Ok("1"),
                "cannot run bash: {e}"
            );
            eprintln!("skipped: cannot run bash: {e}");
            return;
        }
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "check_report.sh failed:\n{stdout}\n{stderr}"
    );
    if stdout.contains("SKIPPED") {
        eprintln!("{stdout}");
        return;
    }
    assert!(
        stdout.contains(": 4 images, 0 not decoded, 0 errors"),
        "{stdout}"
    );
    let (w, _, _) = crate::render::png::decode_rgb8(&std::fs::read(&shot).unwrap());
    assert_eq!(w, 1200);
}

/// Writes a sample report for the headless-browser check and the README picture:
/// `POLARID_SAMPLE_REPORT_DIR=DIR cargo test -p polarid-cli --release -- --ignored
/// write_sample_report`, then `scripts/check_report.sh DIR/report.html OUT.png`.
#[test]
#[ignore = "writes files to $POLARID_SAMPLE_REPORT_DIR"]
fn write_sample_report() {
    let Some(dir) = std::env::var_os("POLARID_SAMPLE_REPORT_DIR") else {
        panic!("set POLARID_SAMPLE_REPORT_DIR");
    };
    let dir = PathBuf::from(dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (report, plots) = sample_report(false);
    for (stem, r) in &plots {
        r.write(&dir, stem).unwrap();
    }
    report.write(&dir, "report").unwrap();
}
