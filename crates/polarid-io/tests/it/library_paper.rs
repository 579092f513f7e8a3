//! The paper's Tables 1 and 2 as data (Thilak, Creusere and Voelz, ICIP 2007, section 7).
//!
//! Training estimates (Table 1, n̂ + ik̂): green paint 1.47 + 0.47i, aluminum 1.64 + 4.56i,
//! copper 0.54 + 3.19i. Test estimates of a second aluminum plate (Table 2): 1.37 + 3.97i
//! (view angle 60°) and 1.60 + 4.34i (50°), both classified as aluminum in the paper.

use polarid_core::classify::{Classifier, ClassifierConfig, Estimate, Prototype, Status};
use polarid_io::library::Library;

const TESTS: [(f64, f64); 2] = [(1.37, 3.97), (1.60, 4.34)];

fn paper_prototypes() -> Vec<Prototype> {
    [
        ("green paint", 1.47, 0.47),
        ("aluminum", 1.64, 4.56),
        ("copper", 0.54, 3.19),
    ]
    .into_iter()
    .map(|(c, n, k)| Prototype {
        class: c.into(),
        n,
        k,
        cov: None,
        category: None,
        source: "paper Table 1".into(),
    })
    .collect()
}

#[test]
fn paper_test_estimates_classify_as_aluminum() {
    let clf = Classifier::new(paper_prototypes(), ClassifierConfig::default()).unwrap();
    for (n, k) in TESTS {
        let d = clf.classify(&Estimate::point(n, k));
        assert_eq!(d.predicted, "aluminum", "{n} + {k}i");
        assert_eq!(d.runner_up.as_deref(), Some("copper"));
        assert!(d.margin > 0.4, "{n} + {k}i: margin {}", d.margin);
    }
}

#[test]
fn paper_test_estimates_are_metals_in_the_builtin_library() {
    let lib = Library::builtin().unwrap();
    let clf = Classifier::new(lib.prototypes(), ClassifierConfig::default()).unwrap();
    for (n, k) in TESTS {
        let d = clf.classify(&Estimate::point(n, k));
        assert_eq!(d.status, Status::Ok);
        let protos = clf.prototypes();
        let near = d.nearest.unwrap();
        // The nearest library material is a metal (nickel for both estimates: the
        // library's aluminum, Rakić 1995, is 1.56 + 7.70i, far from these oxidized,
        // roughened-plate estimates)...
        assert_eq!(
            protos[near.index].category.as_deref(),
            Some("metal"),
            "{n}+{k}i"
        );
        assert_eq!(d.predicted, "nickel");
        let expect = (n - 1.99923f64).hypot(k - 4.206);
        assert!((d.distance - expect).abs() < 1e-12);
        // ...and so are the five nearest: the explanation the report prints.
        for nb in &d.ranked[..5] {
            assert_eq!(protos[nb.index].category.as_deref(), Some("metal"));
        }
        // The nearest non-metal is much farther than the nearest metal.
        let non_metal = d
            .ranked
            .iter()
            .find(|nb| protos[nb.index].category.as_deref() != Some("metal"))
            .unwrap();
        assert!(non_metal.distance > 2.5 * d.distance, "{n}+{k}i");
        assert_eq!(protos[non_metal.index].class, "graphite_o");
    }
}

#[test]
fn paper_reference_values_give_a_metal_but_not_aluminum() {
    // Against the paper's own literature values (Table 1 n, k: aluminum 1.24 + 6.60i,
    // copper 0.40 + 2.95i, green paint 1.39 + 0.34i) both test estimates are nearer to
    // copper (1.41 and 1.84) than to aluminum (2.63 and 2.29): the estimates' k is far
    // below aluminum's literature k, which is why the paper trains on estimates. The
    // category is still right: a metal.
    let lib = Library::paper_2007().unwrap();
    let clf = Classifier::new(lib.prototypes(), ClassifierConfig::default()).unwrap();
    for ((n, k), dcu) in TESTS
        .into_iter()
        .zip([1.4075865870347017, 1.8363278574372277])
    {
        let d = clf.classify(&Estimate::point(n, k));
        assert_eq!(d.predicted, "copper", "{n}+{k}i");
        assert!((d.distance - dcu).abs() < 1e-12);
        assert_eq!(d.runner_up.as_deref(), Some("aluminum"));
        let cat = &clf.prototypes()[d.nearest.unwrap().index].category;
        assert_eq!(cat.as_deref(), Some("metal"));
    }
}
