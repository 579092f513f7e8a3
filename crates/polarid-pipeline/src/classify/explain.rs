//! The one-paragraph explanation of a decision (`polarid classify`'s messages, the demo's
//! notes).

use polarid_core::classify::{Classifier, Decision};

/// A one-paragraph explanation of a decision: nearest prototypes (at most `top`), when
/// categories are known the nearest prototype of another category, and the consistent
/// set (every candidate with its Mahalanobis distance and the test's threshold) when it
/// was tested.
pub fn explain(target: &str, d: &Decision, clf: &Classifier, top: usize) -> String {
    // ok (indexing `protos` below): every index in a decision is one of `clf`'s
    // prototypes, produced by `clf.classify`.
    let protos = clf.prototypes();
    let unit = clf.config().distance_metric().name();
    let cat = |i: usize| {
        protos[i]
            .category
            .as_deref()
            .map(|c| format!(" ({c})"))
            .unwrap_or_default()
    };
    let mut s = format!("{target}: ");
    match (&d.nearest_class, d.nearest) {
        (Some(c), Some(nb)) => {
            if d.predicted == *c {
                s.push_str(c);
            } else {
                s.push_str(&format!("{} (nearest {c})", d.predicted));
            }
            if let Some(category) = &protos[nb.index].category {
                let article = if category.starts_with(['a', 'e', 'i', 'o', 'u']) {
                    "an"
                } else {
                    "a"
                };
                if d.predicted == *c {
                    s.push_str(&format!(", classified as {article} {category}"));
                }
            }
            s.push_str(&format!(" [{unit} distance {:.4}", d.distance));
            if let Some(r) = &d.runner_up {
                s.push_str(&format!(
                    "; runner-up {r} at {:.4}, margin {:.4}",
                    d.runner_up_distance, d.margin
                ));
            }
            s.push(']');
            let near: Vec<String> = d
                .ranked
                .iter()
                .take(top)
                .map(|nb| {
                    format!(
                        "{}{} {:.4}",
                        protos[nb.index].class,
                        cat(nb.index),
                        nb.distance
                    )
                })
                .collect();
            if !near.is_empty() {
                s.push_str(&format!("; nearest: {}", near.join(", ")));
            }
            if let Some(category) = &protos[nb.index].category
                && let Some(other) = d.ranked.iter().find(|o| {
                    protos[o.index]
                        .category
                        .as_ref()
                        .is_some_and(|c| c != category)
                })
            {
                s.push_str(&format!(
                    "; nearest non-{category}: {}{} {:.4}",
                    protos[other.index].class,
                    cat(other.index),
                    other.distance
                ));
            }
            if d.set_tested {
                let cfg = clf.config();
                let list: Vec<String> = d
                    .candidates
                    .iter()
                    .map(|c| {
                        let cat = c
                            .category
                            .as_deref()
                            .map(|x| format!(" ({x})"))
                            .unwrap_or_default();
                        format!("{}{cat} {:.3}", c.class, c.distance)
                    })
                    .collect();
                s.push_str(&format!(
                    "; consistent at {}% (Mahalanobis <= {:.3}): {}",
                    cfg.confidence * 100.0,
                    polarid_core::classify::chi2_2dof_quantile(cfg.confidence).sqrt(),
                    if list.is_empty() {
                        "none".to_string()
                    } else {
                        list.join(", ")
                    }
                ));
                if d.candidates.len() > 1
                    && let Some(cat) = &d.set_category
                {
                    s.push_str(&format!(", all {cat}"));
                }
            }
            if !d.reason.is_empty() && d.status != polarid_core::classify::Status::Ambiguous {
                s.push_str(&format!("; {}", d.reason));
            }
        }
        _ => s.push_str(&format!("{} ({})", d.predicted, d.reason)),
    }
    s
}
