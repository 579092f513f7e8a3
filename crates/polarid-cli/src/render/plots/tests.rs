//! Tests of the plots.

use std::path::Path;

use plotters::prelude::*;

use super::dolp::*;
use super::maps::*;
use super::nk::*;
use super::style::*;
use super::*;
use crate::render::Rendered;

/// `(width, height, RGB bytes)` of a PNG.
fn decode(png: &[u8]) -> (u32, u32, Vec<u8>) {
    crate::render::png::decode_rgb8(png)
}

fn assert_outputs(r: &Rendered, size: PlotSize, texts: &[&str]) {
    let (w, h, _) = decode(&r.png);
    assert_eq!((w, h), (size.width, size.height));
    assert!(
        r.svg.starts_with("<svg"),
        "not an SVG: {}",
        &r.svg[..40.min(r.svg.len())]
    );
    assert!(r.svg.trim_end().ends_with("</svg>"));
    for t in texts {
        assert!(r.svg.contains(t), "SVG lacks the text {t:?}");
    }
}

/// Number of pixels of `png` within `tol` of colour `c`.
fn count_colour(png: &[u8], c: RGBColor, tol: i32) -> usize {
    let (_, _, rgb) = decode(png);
    rgb.chunks_exact(3)
        .filter(|p| {
            (p[0] as i32 - c.0 as i32).abs() <= tol
                && (p[1] as i32 - c.1 as i32).abs() <= tol
                && (p[2] as i32 - c.2 as i32).abs() <= tol
        })
        .count()
}

fn synthetic_series() -> Vec<DolpSeries> {
    let targets = [
        ("green paint", 1.39, 0.34),
        ("aluminum", 1.24, 6.6),
        ("copper", 0.4, 2.95),
    ];
    targets
        .iter()
        .map(|&(name, n, k)| {
            let points = (0..10)
                .map(|i| {
                    let beta = 47.5 + 2.5 * i as f64;
                    let p = polarid_core::dop::dop(n, k, beta.to_radians());
                    DolpPoint {
                        beta_deg: beta,
                        dolp: p + 0.01 * ((i as f64) * 1.7).sin(),
                        dolp_se: Some(0.01),
                    }
                })
                .collect();
            DolpSeries {
                label: name.into(),
                points,
                curve: eq9_curve(n, k, 45.0, 72.0, 100),
                curve_label: Some(format!("fit n = {n:.2}, k = {k:.2}")),
            }
        })
        .collect()
}

#[test]
fn dolp_plot_writes_png_and_svg_with_labels() {
    let dir = tempfile::tempdir().unwrap();
    let size = PlotSize::REPORT;
    let r = dolp_vs_beta("DoLP against β", &synthetic_series(), size).unwrap();
    assert_outputs(
        &r,
        size,
        &[
            "β (degrees)",
            "DoLP",
            "green paint (data)",
            "fit n = 0.40, k = 2.95",
        ],
    );
    let files = r.write(dir.path(), "dolp_beta").unwrap();
    assert_eq!(files.png, dir.path().join("dolp_beta.png"));
    let on_disk = std::fs::read(&files.png).unwrap();
    assert_eq!(decode(&on_disk).0, size.width);
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    assert!(svg.contains("β (degrees)"));
    // The series colours are really drawn (curves and markers), text really rendered.
    assert!(count_colour(&r.png, PALETTE[0], 10) > 200);
    assert!(count_colour(&r.png, PALETTE[2], 10) > 200);
    assert!(
        count_colour(&r.png, BLACK, 60) > 500,
        "no text drawn in the PNG"
    );
}

#[test]
fn eq9_curve_matches_core() {
    let c = eq9_curve(1.24, 6.6, 40.0, 80.0, 5);
    assert_eq!(c.len(), 5);
    assert_eq!(c[0].0, 40.0);
    assert_eq!(c[4].0, 80.0);
    assert_eq!(
        c[2].1,
        polarid_core::dop::dop(1.24, 6.6, 60f64.to_radians())
    );
    assert!(sample_curve(0.0, 1.0, 0, |x| x).is_empty());
}

#[test]
fn empty_data_draws_notices() {
    let size = PlotSize {
        width: 640,
        height: 400,
    };
    let r = dolp_vs_beta("empty", &[], size).unwrap();
    assert_outputs(&r, size, &["No DoLP data to plot"]);
    let nan = DolpSeries {
        label: "x".into(),
        points: vec![DolpPoint {
            beta_deg: f64::NAN,
            dolp: 0.3,
            dolp_se: None,
        }],
        curve: vec![],
        curve_label: None,
    };
    let r = dolp_vs_beta("nan", &[nan], size).unwrap();
    assert_outputs(&r, size, &["No DoLP data to plot"]);
    let r = nk_plane("empty", &[], &[], size).unwrap();
    assert_outputs(&r, size, &["No (n, k) values to plot"]);
    let r = class_map("empty", 0, 0, &[], &[], size).unwrap();
    assert_outputs(&r, size, &["Empty image"]);
    let r = scalar_map::<f32>("all NaN", 2, 1, &[f32::NAN, f32::NAN], None, "n", size).unwrap();
    assert_outputs(&r, size, &["no finite values"]);
}

#[test]
fn bad_inputs_are_errors() {
    let e = class_map("x", 3, 2, &[0; 5], &[], PlotSize::REPORT).unwrap_err();
    assert!(e.to_string().contains("5 values, expected 3 × 2"), "{e}");
    let e = scalar_map(
        "x",
        1,
        1,
        &[0.5f64],
        Some((1.0, 0.0)),
        "n",
        PlotSize::REPORT,
    )
    .unwrap_err();
    assert!(e.to_string().contains("colour range 1..0"), "{e}");
    let e = dolp_vs_beta(
        "x",
        &[],
        PlotSize {
            width: 10,
            height: 10,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("10x10"), "{e}");
    let r = dolp_vs_beta("x", &[], PlotSize::REPORT).unwrap();
    assert!(r.write(Path::new("/nonexistent-dir-polarid"), "a").is_err());
    assert!(r.write(Path::new("."), "a/b").is_err());
}

#[test]
fn ellipse_is_the_one_sigma_contour() {
    // Every point x of the ellipse satisfies (x - c)ᵀ Σ⁻¹ (x - c) = 1.
    let (n, k, sn, sk, rho) = (1.4, 4.0, 0.05, 0.3, 0.8);
    let pts = covariance_ellipse(n, k, sn, sk, rho, 64);
    assert_eq!(pts.len(), 65);
    let det = sn * sn * sk * sk * (1.0 - rho * rho);
    for (x, y) in pts {
        let (dx, dy) = (x - n, y - k);
        let m = (sk * sk * dx * dx - 2.0 * rho * sn * sk * dx * dy + sn * sn * dy * dy) / det;
        assert!((m - 1.0).abs() < 1e-9, "Mahalanobis² = {m}");
    }
    assert!(covariance_ellipse(0.0, 0.0, f64::NAN, 1.0, 0.0, 10).is_empty());
}

#[test]
fn voronoi_cells_partition_by_nearest_prototype() {
    let sites = [(1.39, 0.34), (1.24, 6.6), (0.4, 2.95)];
    // Sample points: inside a cell iff that prototype is the nearest one.
    let inside = |poly: &[(f64, f64)], p: (f64, f64)| {
        (0..poly.len()).all(|i| {
            let a = poly[i];
            let b = poly[(i + 1) % poly.len()];
            (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) >= -1e-12
        })
    };
    let cells: Vec<_> = (0..3)
        .map(|i| voronoi_cell(&sites, i, 0.0..2.0, 0.0..8.0))
        .collect();
    for gx in 0..20 {
        for gy in 0..20 {
            let p = (0.05 + 0.1 * gx as f64, 0.1 + 0.4 * gy as f64);
            let d = |s: (f64, f64)| (s.0 - p.0).powi(2) + (s.1 - p.1).powi(2);
            let nearest = (0..3)
                .min_by(|&a, &b| d(sites[a]).total_cmp(&d(sites[b])))
                .unwrap();
            for (i, c) in cells.iter().enumerate() {
                assert_eq!(inside(c, p), i == nearest, "point {p:?} cell {i}");
            }
        }
    }
}

#[test]
fn nk_plane_draws_regions_prototypes_and_ellipses() {
    let protos = vec![
        Prototype {
            class: "green paint".into(),
            n: 1.47,
            k: 0.47,
        },
        Prototype {
            class: "aluminum".into(),
            n: 1.64,
            k: 4.56,
        },
        Prototype {
            class: "copper".into(),
            n: 0.54,
            k: 3.19,
        },
    ];
    let ests = vec![
        NkEstimate {
            label: "test, θr = 60°".into(),
            n: 1.37,
            k: 3.97,
            n_se: 0.08,
            k_se: 0.3,
            corr: 0.6,
            predicted: Some("aluminum".into()),
            answer: None,
            regions: Vec::new(),
        },
        NkEstimate {
            label: "test, θr = 50°".into(),
            n: 1.60,
            k: 4.34,
            n_se: 0.1,
            k_se: 0.4,
            corr: -0.2,
            predicted: None,
            answer: None,
            regions: Vec::new(),
        },
    ];
    let size = PlotSize::REPORT;
    let r = nk_plane("(n, k) plane", &protos, &ests, size).unwrap();
    assert_outputs(
        &r,
        size,
        &[
            "n (real part of N)",
            "k (imaginary part of N)",
            "copper",
            "test, θr = 50°",
        ],
    );
    // All three decision regions are shaded.
    for (i, &c) in PALETTE.iter().take(3).enumerate() {
        let n = count_colour(&r.png, tint(c, 0.18), 2);
        assert!(n > 2000, "region {i} has {n} pixels");
        // Prototype markers in full colour.
        assert!(count_colour(&r.png, c, 8) > 50, "prototype {i}");
    }
    // No fourth class colour anywhere.
    assert_eq!(count_colour(&r.png, tint(PALETTE[3], 0.18), 2), 0);
    assert!(r.svg.matches("<polygon").count() >= 3);
}

#[test]
fn class_map_colours_pixels_and_lists_classes() {
    let (w, h) = (40usize, 30usize);
    let classes: Vec<u16> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if y < 5 {
                0
            } else if x < 20 {
                1
            } else if x < 30 {
                2
            } else {
                3
            }
        })
        .collect();
    let names = vec!["aluminum".to_string(), "copper".to_string()];
    let size = PlotSize::REPORT;
    let r = class_map("Material map", w, h, &classes, &names, size).unwrap();
    assert_outputs(
        &r,
        size,
        &[
            "x (pixel column)",
            "y (pixel row)",
            "aluminum (42 %)",
            "class 3",
            "unknown (17 %)",
        ],
    );
    assert!(r.svg.contains("<image") && r.svg.contains("data:image/png;base64,"));
    let a = count_colour(&r.png, PALETTE[0], 0);
    let c = count_colour(&r.png, PALETTE[1], 0);
    assert!(a > 10_000, "aluminum pixels: {a}");
    // Aluminium covers twice the area of copper (20 vs 10 columns).
    let ratio = a as f64 / c as f64;
    assert!((ratio - 2.0).abs() < 0.15, "area ratio {ratio}");
}

#[test]
fn scalar_map_uses_viridis_and_colour_bar() {
    let (w, h) = (64usize, 48usize);
    let vals: Vec<f32> = (0..w * h)
        .map(|i| (i % w) as f32 / (w - 1) as f32)
        .collect();
    let size = PlotSize::REPORT;
    let r = scalar_map("DoLP map", w, h, &vals, None, "DoLP", size).unwrap();
    assert_outputs(&r, size, &["DoLP map", "DoLP", "x (pixel column)"]);
    let lo = count_colour(&r.png, viridis(0.0), 3);
    let hi = count_colour(&r.png, viridis(1.0), 3);
    assert!(lo > 500 && hi > 500, "ends of the map: {lo} {hi}");
    // NaN pixels are grey.
    let mut with_nan = vals.clone();
    for v in with_nan.iter_mut().take(w * 10) {
        *v = f32::NAN;
    }
    let r = scalar_map("n", w, h, &with_nan, Some((0.0, 1.0)), "n", size).unwrap();
    assert!(count_colour(&r.png, NO_DATA, 0) > 2000);
}

#[test]
fn viridis_end_points_and_palette() {
    assert_eq!(viridis(0.0), RGBColor(0x44, 0x01, 0x54));
    assert_eq!(viridis(1.0), RGBColor(0xfd, 0xe7, 0x25));
    assert_eq!(viridis(2.0), viridis(1.0));
    assert_eq!(viridis(f64::NAN), NO_DATA);
    assert_ne!(class_colour(9), class_colour(10));
}

#[test]
fn legend_text_is_wrapped_not_cut() {
    ensure_fonts().unwrap();
    let mut buf = vec![255u8; 300 * 200 * 3];
    let root = BitMapBackend::with_buffer(&mut buf, (300, 200)).into_drawing_area();
    let style = font(LEGEND_SIZE);
    let s = "test_1, θr = 60°: ambiguous: aluminum, copper, brass; 95% set: aluminum_oxide_film";
    let lines = wrap_text(&root, s, &style, 200);
    assert!(lines.len() >= 3, "{lines:?}");
    // Every character is kept, in order (spaces at the breaks aside).
    assert_eq!(lines.concat().replace(' ', ""), s.replace(' ', ""));
    for l in &lines {
        let (w, _) = root.estimate_text_size(l, &style).unwrap();
        assert!(w <= 200, "{l:?} is {w} px wide");
    }
    // A word wider than a line is split, not dropped.
    let long = "a".repeat(80);
    let lines = wrap_text(&root, &long, &style, 100);
    assert!(lines.len() > 1 && lines.concat() == long, "{lines:?}");
    assert_eq!(
        wrap_text(&root, "short", &style, 200),
        vec!["short".to_string()]
    );
}

fn library_proto(
    class: &str,
    n: f64,
    k: f64,
    cov: Option<polarid_core::classify::Cov2>,
) -> polarid_core::classify::Prototype {
    polarid_core::classify::Prototype {
        class: class.into(),
        n,
        k,
        cov,
        category: Some("metal".into()),
        source: "test".into(),
    }
}

fn fit_row(
    target: &str,
    n: f64,
    k: f64,
    n_se: f64,
    k_se: f64,
    corr: f64,
) -> polarid_io::table::fits::FitRow {
    polarid_io::table::fits::FitRow {
        target: target.into(),
        n,
        k,
        n_se,
        k_se,
        nk_corr: corr,
        status: polarid_core::FitStatus::Ok,
        ..Default::default()
    }
}

#[test]
fn nk_plane_draws_the_regions_that_decide_the_sets_with_the_answers() {
    use polarid_core::classify::{Classifier, ClassifierConfig, Cov2};
    use polarid_pipeline::classify::{classification_row, estimate_of};
    let protos = vec![
        library_proto("gold", 0.2, 3.3, None),
        library_proto("copper", 0.25, 3.4, None),
        library_proto("silver", 0.05, 4.3, None),
    ];
    let clf = Classifier::new(protos.clone(), ClassifierConfig::set(0.95)).unwrap();
    let fits = [
        fit_row("t1", 0.22, 3.35, 0.05, 0.1, 0.2),
        fit_row("t2", 1.5, 1.0, 0.05, 0.1, 0.0),
        fit_row("t3", 0.06, 4.25, 0.04, 0.1, -0.3),
    ];
    let rows: Vec<_> = fits
        .iter()
        .map(|f| classification_row(f, &clf.classify(&estimate_of(f)), &clf))
        .collect();
    let ests: Vec<NkEstimate> = fits
        .iter()
        .map(|f| NkEstimate::from_fit(f.target.clone(), f, &rows, Some(&clf)))
        .collect();
    assert_eq!(ests[0].answer.as_deref(), Some("ambiguous: gold, copper"));
    assert_eq!(ests[1].answer.as_deref(), Some("unknown (none at 95%)"));
    assert_eq!(ests[2].answer.as_deref(), Some("silver"));
    let threshold = polarid_core::classify::chi2_2dof_quantile(0.95).sqrt();
    for (e, f) in ests.iter().zip(&fits) {
        // A library: one region, the estimate's own covariance.
        assert_eq!(e.regions.len(), 1, "{}", e.label);
        let r = &e.regions[0];
        assert_eq!(r.with_prototype, None);
        assert_eq!(r.confidence, 0.95);
        // Every drawn point is on the contour of the set distance (no k = 0 cut here).
        let est = estimate_of(f);
        for &(n, k) in &r.boundary {
            let d = Classifier::set_distance(&est, &library_proto("x", n, k, None)).unwrap();
            assert!((d - threshold).abs() < 1e-8, "{}: {d}", e.label);
        }
    }
    let plot_protos: Vec<Prototype> = protos
        .iter()
        .map(|p| Prototype {
            class: p.class.clone(),
            n: p.n,
            k: p.k,
        })
        .collect();
    let size = PlotSize::REPORT;
    let r = nk_plane("sets", &plot_protos, &ests, size).unwrap();
    assert_outputs(
        &r,
        size,
        &[
            "Estimates: answer (95% region)",
            "t1: ambiguous: gold, copper",
            "t2: unknown (none at 95%)",
            "t3: silver",
            "Σ only",
        ],
    );
    // Prototypes with a covariance (a trained model): one region per covariance, dashed.
    let cov = Cov2::from_se(0.03, 0.05, 0.1);
    let model: Vec<_> = protos
        .iter()
        .map(|p| library_proto(&p.class, p.n, p.k, cov))
        .collect();
    let clf = Classifier::new(model, ClassifierConfig::default()).unwrap();
    let rows: Vec<_> = fits
        .iter()
        .map(|f| classification_row(f, &clf.classify(&estimate_of(f)), &clf))
        .collect();
    let e = NkEstimate::from_fit("t1".into(), &fits[0], &rows, Some(&clf));
    // Nearest rule: the answer, then the set that differs from it.
    assert_eq!(e.answer.as_deref(), Some("gold; 95% set: gold, copper"));
    assert_eq!(e.regions.len(), 1, "all three share one covariance");
    assert_eq!(
        e.regions[0].with_prototype.as_deref(),
        Some(
            &[
                "gold".to_string(),
                "copper".to_string(),
                "silver".to_string()
            ][..]
        )
    );
    let r = nk_plane("model", &plot_protos, &[e], size).unwrap();
    assert_outputs(&r, size, &["with gold, copper"]);
    assert!(r.svg.contains("stroke-dasharray") || r.svg.matches("<polyline").count() > 20);
}

#[test]
fn confidence_regions_are_cut_at_n_and_k_zero() {
    // An ellipse reaching n < 0 and k < 0.
    let ell = covariance_ellipse(0.2, 0.1, 0.5, 0.3, 0.4, 200);
    assert!(ell.iter().any(|p| p.0 < -0.1) && ell.iter().any(|p| p.1 < -0.05));
    let (pieces, cut) = clip_to_physical(&ell);
    assert!(cut);
    assert!(!pieces.is_empty());
    let pts: Vec<(f64, f64)> = pieces.iter().flatten().copied().collect();
    assert!(pts.iter().all(|p| p.0 >= 0.0 && p.1 >= 0.0), "{pts:?}");
    // The kept boundary reaches the cut lines (open ends on n = 0 and k = 0).
    assert!(pts.iter().any(|p| p.0 == 0.0) && pts.iter().any(|p| p.1 == 0.0));
    // Every kept point of the original boundary is still there.
    let kept = ell.iter().filter(|p| p.0 >= 0.0 && p.1 >= 0.0).count();
    assert!(pts.len() >= kept, "{} < {kept}", pts.len());
    // A region inside the quadrant is drawn whole and closed.
    let inside = covariance_ellipse(2.0, 3.0, 0.1, 0.2, 0.0, 50);
    let (pieces, cut) = clip_to_physical(&inside);
    assert!(!cut);
    assert_eq!(pieces.len(), 1);
    assert_eq!(pieces[0].first(), pieces[0].last());
    // Entirely outside: nothing drawn.
    let out = covariance_ellipse(-2.0, 1.0, 0.1, 0.1, 0.0, 50);
    assert!(clip_to_physical(&out).0.is_empty());
}

#[test]
fn answer_map_colours_unknown_pixels_by_reason_and_outlines_regions() {
    use polarid_core::map::reason;
    let (w, h) = (40usize, 30usize);
    // Rows 0-4: saturated; 5-9: dark; 10-14: rejected; 15-19: fit not ok;
    // 20-24: aluminum; 25-29: ambiguous.
    let kind = |i: usize| i / w / 5;
    let classes: Vec<u16> = (0..w * h)
        .map(|i| match kind(i) {
            4 => 1,
            5 => 2,
            _ => 0,
        })
        .collect();
    let reasons: Vec<u8> = (0..w * h)
        .map(|i| match kind(i) {
            0 => reason::SATURATED,
            1 => reason::DARK,
            2 => reason::REJECTED,
            3 => reason::FIT_ILL_CONDITIONED,
            4 => reason::CLASSIFIED,
            _ => reason::AMBIGUOUS,
        })
        .collect();
    let names = vec!["aluminum".to_string(), "ambiguous".to_string()];
    let size = PlotSize::REPORT;
    let data = ClassMap {
        width: w,
        height: h,
        classes: &classes,
        names: &names,
        reasons: Some(&reasons),
        regions: vec![MapRegion {
            name: "plate_al".into(),
            rect: [2.0, 20.0, 30.0, 5.0],
        }],
    };
    let r = answer_map("Material map", &data, size).unwrap();
    if let Ok(dir) = std::env::var("POLARID_PLOT_DIR") {
        std::fs::write(Path::new(&dir).join("answer_map.png"), &r.png).unwrap();
    }
    assert_outputs(
        &r,
        size,
        &[
            "Answers (pixel share)",
            "aluminum (17 %)",
            "ambiguous (17 %)",
            "unknown: saturated",
            "unknown: dark or invalid",
            "unknown: rejected",
            "unknown: no usable fit",
            "plate_al",
        ],
    );
    // The region's label is drawn after (over) the image in the SVG.
    let svg = &r.svg;
    assert!(
        svg.rfind("plate_al") > svg.find("<image"),
        "label under the image"
    );
    let [sr, sg, sb] = crate::render::views::SATURATED_RGB;
    let [dr, dg, db] = crate::render::views::DARK_RGB;
    for (c, what) in [
        (RGBColor(sr, sg, sb), "saturated"),
        (RGBColor(dr, dg, db), "dark"),
        (REJECTED_COLOUR, "rejected"),
        (NO_DATA, "no fit"),
        (AMBIGUOUS_COLOUR, "ambiguous"),
        (PALETTE[0], "aluminum"),
    ] {
        let n = count_colour(&r.png, c, 0);
        assert!(n > 2_000, "{what}: {n} pixels of {c:?}");
    }
    // The outline is black over the image.
    let bare = answer_map(
        "Material map",
        &ClassMap {
            regions: Vec::new(),
            ..data.clone()
        },
        size,
    )
    .unwrap();
    assert!(count_colour(&r.png, BLACK, 0) > count_colour(&bare.png, BLACK, 0) + 100);
}
