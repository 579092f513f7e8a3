//! Trained model JSON: round trip, provenance, and refusal of other format versions.

use std::path::Path;

use polarid_core::classify::Cov2;
use polarid_io::model::{FORMAT_VERSION, Model, ModelPrototype, PrototypeSource, cov_matrix};

fn sample() -> Model {
    let cov = Cov2::from_se(0.1, 0.2, -0.3).unwrap();
    Model::new(vec![
        ModelPrototype {
            wavelength_nm: None,
            class: "aluminum".into(),
            n: 1.64,
            k: 4.56,
            covariance: Some(cov_matrix(&cov)),
            sample_covariance: None,
            film_shifts: None,
            category: None,
            source: PrototypeSource {
                file: "fits.csv".into(),
                line: 3,
                target: "A".into(),
            },
        },
        ModelPrototype {
            wavelength_nm: None,
            class: "aluminum".into(),
            n: 1.5,
            k: 4.4,
            covariance: None,
            sample_covariance: None,
            film_shifts: None,
            category: Some("metal".into()),
            source: PrototypeSource {
                file: "other/fits.csv".into(),
                line: 7,
                target: "A2".into(),
            },
        },
    ])
}

#[test]
fn model_round_trip_keeps_prototypes_and_provenance() {
    let m = sample();
    let mut buf = Vec::new();
    m.write(&mut buf, Path::new("m.json")).unwrap();
    let text = String::from_utf8(buf).unwrap();
    assert!(text.contains("\"format_version\": 1"), "{text}");
    let back = Model::parse(Path::new("m.json"), &text).unwrap();
    assert_eq!(back, m);
    let protos = back.prototypes();
    assert_eq!(protos.len(), 2);
    assert_eq!(protos[0].source, "fits.csv:3 target A");
    let c = protos[0].cov.unwrap();
    let (sn, sk, r) = c.to_se();
    assert!((sn - 0.1).abs() < 1e-15 && (sk - 0.2).abs() < 1e-15 && (r + 0.3).abs() < 1e-12);
    assert!(protos[1].cov.is_none());
}

#[test]
fn model_of_another_version_is_refused_naming_the_version() {
    let text = serde_json::to_string(&sample())
        .unwrap()
        .replace("\"format_version\":1", "\"format_version\":2");
    let e = Model::parse(Path::new("m.json"), &text)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.json")
            && e.contains("version 2")
            && e.contains(&format!("version {FORMAT_VERSION}")),
        "{e}"
    );
    assert!(e.contains("polarid train"), "{e}");
}

#[test]
fn model_errors_name_the_problem() {
    let e = Model::parse(Path::new("m.json"), "{\"prototypes\": []}")
        .unwrap_err()
        .to_string();
    assert!(e.contains("format") && e.contains("missing"), "{e}");
    let e = Model::parse(Path::new("m.json"), "not json")
        .unwrap_err()
        .to_string();
    assert!(e.contains("not valid JSON"), "{e}");
    let text = serde_json::to_string(&sample())
        .unwrap()
        .replace("\"class\":\"aluminum\"", "\"class\":\"unknown\"");
    let e = Model::parse(Path::new("m.json"), &text)
        .unwrap_err()
        .to_string();
    assert!(e.contains("prototypes[0]") && e.contains("reserved"), "{e}");
    let text = serde_json::to_string(&sample())
        .unwrap()
        .replace("\"k\":4.56", "\"k\":-1.0");
    let e = Model::parse(Path::new("m.json"), &text)
        .unwrap_err()
        .to_string();
    assert!(e.contains("k = -1"), "{e}");
}
