//! The labelled and unlabelled points of the `(n, k)` plane: [`Prototype`]s (training
//! estimates or literature values, paper section 6 and Table 1) and the [`Estimate`]s
//! compared with them (Table 2), and the grouping of prototype classes into categories.

use std::collections::BTreeMap;

use super::Cov2;
use crate::status::FitStatus;

/// A labelled point of the `(n, k)` plane that estimates are compared with: a training
/// estimate or a literature value.
#[derive(Debug, Clone, PartialEq)]
pub struct Prototype {
    /// Class (material) name.
    pub class: String,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index (`k >= 0`).
    pub k: f64,
    /// Covariance of `(n, k)` when the prototype is itself an estimate.
    pub cov: Option<Cov2>,
    /// Broad category (`metal`, `dielectric`, `semiconductor`, `other`) when known.
    pub category: Option<String>,
    /// Where the prototype came from (e.g. `fits.csv:3 target A`, `library builtin`).
    pub source: String,
}

/// An estimate to classify.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Estimated real part of the index.
    pub n: f64,
    /// Estimated imaginary part of the index.
    pub k: f64,
    /// Covariance of the estimate (`None` when the fit gave no standard errors).
    pub cov: Option<Cov2>,
    /// Status of the fit: [`FitStatus::Ok`], or why it should not be trusted.
    pub fit_status: FitStatus,
}

impl Estimate {
    /// An estimate with status `ok` and no covariance.
    pub fn point(n: f64, k: f64) -> Self {
        Self {
            n,
            k,
            cov: None,
            fit_status: FitStatus::Ok,
        }
    }
}

/// Group the classes of a set of prototypes with their categories (first category seen
/// per class), e.g. to report "classified as a metal".
pub fn class_categories(prototypes: &[Prototype]) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    for p in prototypes {
        if let Some(c) = &p.category {
            m.entry(p.class.clone()).or_insert_with(|| c.clone());
        }
    }
    m
}
