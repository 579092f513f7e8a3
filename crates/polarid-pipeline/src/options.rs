//! The classifier's options as the front ends receive them, checked once.
//!
//! `polarid classify`, `polarid evaluate` and the Python functions `classify`,
//! `classify_table` and `evaluate` take the same decision options. The command line and
//! Python only translate their names into [`ClassifierOptions`];
//! [`ClassifierOptions::config`] checks the combination and builds the core's
//! [`ClassifierConfig`]. Errors name the options as the command line spells them
//! (`--rule`, `--metric`, `--k`, `--reject`, `--max-distance`, `--confidence`); the
//! Python functions' keywords are the same words (`neighbours` for `--k`).

use polarid_core::classify::{ClassifierConfig, Metric, Reject, Rule};

use crate::error::{PipelineError, Result, ensure};

/// The decision options, unchecked. The defaults are the command line's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassifierOptions {
    /// Decision rule: the set rule (default) or the paper's nearest neighbour.
    pub rule: Rule,
    /// Confidence of the consistent set (default 0.95).
    pub confidence: f64,
    /// Metric of the nearest rule (`None`: Euclidean, the paper's); the set rule uses the
    /// Mahalanobis distance.
    pub metric: Option<Metric>,
    /// Prototypes that vote (nearest rule; default 1).
    pub neighbours: usize,
    /// χ² gate probability of the nearest rule's reject option.
    pub reject: Option<f64>,
    /// Distance gate of the nearest rule's reject option.
    pub max_distance: Option<f64>,
}

impl Default for ClassifierOptions {
    fn default() -> Self {
        Self {
            rule: Rule::Set,
            confidence: 0.95,
            metric: None,
            neighbours: 1,
            reject: None,
            max_distance: None,
        }
    }
}

/// Parse `set` or `nearest` (error naming `--rule`).
pub fn parse_rule(s: &str) -> Result<Rule> {
    match s {
        "set" => Ok(Rule::Set),
        "nearest" => Ok(Rule::Nearest),
        _ => Err(PipelineError::config(
            "--rule",
            format!("{s:?}"),
            "must be \"set\" or \"nearest\"",
        )),
    }
}

/// Parse `euclidean` or `mahalanobis` (error naming `--metric`).
pub fn parse_metric(s: &str) -> Result<Metric> {
    match s {
        "euclidean" => Ok(Metric::Euclidean),
        "mahalanobis" => Ok(Metric::Mahalanobis),
        _ => Err(PipelineError::config(
            "--metric",
            format!("{s:?}"),
            "must be \"euclidean\" or \"mahalanobis\"",
        )),
    }
}

impl ClassifierOptions {
    /// The checked classifier settings.
    ///
    /// Errors ([`PipelineError::Config`]): a confidence outside `(0, 1)`; a nearest-rule
    /// option (`--metric euclidean`, `--k` ≠ 1, `--reject`, `--max-distance`) with the set
    /// rule; both reject options; any value the core refuses.
    pub fn config(&self) -> Result<ClassifierConfig> {
        let c = self.confidence;
        ensure(c > 0.0 && c < 1.0, "--confidence", c, "must be in (0, 1)")?;
        if self.rule == Rule::Set {
            let bad = match (self.metric, self.neighbours, self.reject, self.max_distance) {
                (Some(Metric::Euclidean), ..) => Some(("--metric", "euclidean".to_string())),
                (_, k, ..) if k != 1 => Some(("--k", k.to_string())),
                (_, _, Some(p), _) => Some(("--reject", p.to_string())),
                (_, _, _, Some(d)) => Some(("--max-distance", d.to_string())),
                _ => None,
            };
            if let Some((opt, v)) = bad {
                return Err(PipelineError::config(
                    opt,
                    v,
                    "is an option of --rule nearest (the set rule uses the Mahalanobis \
                     distance and rejects by --confidence)",
                ));
            }
            return Ok(ClassifierConfig::set(self.confidence));
        }
        let reject = match (self.reject, self.max_distance) {
            (Some(p), Some(d)) => {
                return Err(PipelineError::config(
                    "--reject",
                    format!("{p} with --max-distance {d}"),
                    "and --max-distance exclude each other",
                ));
            }
            (Some(p), None) => Reject::Chi2 { p },
            (None, Some(d)) => Reject::MaxDistance(d),
            (None, None) => Reject::Never,
        };
        let cfg = ClassifierConfig {
            metric: self.metric.unwrap_or(Metric::Euclidean),
            k: self.neighbours,
            reject,
            rule: Rule::Nearest,
            confidence: self.confidence,
        };
        cfg.validate()
            .map_err(|e| PipelineError::config("classifier option", e.to_string(), "is invalid"))?;
        Ok(cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_set_rule_at_95_percent() {
        let c = ClassifierOptions::default().config().expect("defaults");
        assert_eq!(c, ClassifierConfig::set(0.95));
    }

    #[test]
    fn nearest_options_under_the_set_rule_are_refused_naming_the_option() {
        for (o, flag) in [
            (
                ClassifierOptions {
                    neighbours: 3,
                    ..Default::default()
                },
                "--k",
            ),
            (
                ClassifierOptions {
                    reject: Some(0.99),
                    ..Default::default()
                },
                "--reject",
            ),
            (
                ClassifierOptions {
                    max_distance: Some(1.0),
                    ..Default::default()
                },
                "--max-distance",
            ),
            (
                ClassifierOptions {
                    metric: Some(Metric::Euclidean),
                    ..Default::default()
                },
                "--metric",
            ),
        ] {
            let e = o.config().expect_err("refused").to_string();
            assert!(e.starts_with(flag), "{e}");
            assert!(e.contains("--rule nearest"), "{e}");
        }
    }

    #[test]
    fn bad_values_are_refused() {
        for c in [0.0, 1.0, f64::NAN, -0.5] {
            let o = ClassifierOptions {
                confidence: c,
                ..Default::default()
            };
            assert!(
                o.config()
                    .expect_err("refused")
                    .to_string()
                    .contains("--confidence")
            );
        }
        let both = ClassifierOptions {
            rule: Rule::Nearest,
            reject: Some(0.9),
            max_distance: Some(2.0),
            ..Default::default()
        };
        assert!(both.config().is_err());
        let zero_k = ClassifierOptions {
            rule: Rule::Nearest,
            neighbours: 0,
            ..Default::default()
        };
        assert!(zero_k.config().is_err());
    }

    #[test]
    fn nearest_rule_builds_the_papers_classifier() {
        let o = ClassifierOptions {
            rule: Rule::Nearest,
            metric: Some(Metric::Mahalanobis),
            neighbours: 3,
            reject: Some(0.99),
            ..Default::default()
        };
        let c = o.config().expect("valid");
        assert_eq!(c.metric, Metric::Mahalanobis);
        assert_eq!(c.k, 3);
        assert_eq!(c.reject, Reject::Chi2 { p: 0.99 });
        assert_eq!(c.rule, Rule::Nearest);
        assert_eq!(parse_rule("set").expect("set"), Rule::Set);
        assert!(parse_metric("manhattan").is_err());
    }
}
