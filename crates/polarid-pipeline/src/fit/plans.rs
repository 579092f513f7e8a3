//! A cache of [`FitPlan`]s keyed by their β set and search box, shared by the table fit
//! (one plan per distinct β set of a measurements file) and the Python `fit_nk` (the
//! last few plans across calls).

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;

use polarid_core::CoreError;
use polarid_core::fit::{FitOptions, FitPlan};

/// Key of a cached plan: the β values (radians) and the box, bit for bit.
type PlanKey = (Vec<u64>, [u64; 4]);

/// Plans built by [`FitPlan::new`], reused when the same β set and box come again.
///
/// Building a plan costs a grid of model curves (~0.2 ms at T = 10); targets of one
/// capture set, or repeated calls with the same angles, share one. With a capacity the
/// oldest plan is dropped first.
#[derive(Debug, Default)]
pub struct PlanCache {
    plans: HashMap<PlanKey, Arc<FitPlan>>,
    order: VecDeque<PlanKey>,
    capacity: Option<usize>,
}

impl PlanCache {
    /// A cache that keeps every plan it builds.
    pub fn unbounded() -> Self {
        Self::default()
    }

    /// A cache that keeps at most `capacity` (≥ 1) plans, dropping the oldest.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            capacity: Some(capacity.max(1)),
            ..Self::default()
        }
    }

    /// Number of plans held.
    pub fn len(&self) -> usize {
        self.plans.len()
    }

    /// True when no plan is held.
    pub fn is_empty(&self) -> bool {
        self.plans.is_empty()
    }

    /// The plan of `betas` (radians) and `opts`: the cached one, or a new one (errors of
    /// [`FitPlan::new`]: fewer than 3 angles, an angle outside (0, 90°), a bad box).
    pub fn get(&mut self, betas: &[f64], opts: FitOptions) -> Result<Arc<FitPlan>, CoreError> {
        let b = opts.bounds;
        let key: PlanKey = (
            betas.iter().map(|x| x.to_bits()).collect(),
            [b.n_min, b.n_max, b.k_min, b.k_max].map(f64::to_bits),
        );
        if let Some(p) = self.plans.get(&key) {
            return Ok(Arc::clone(p));
        }
        let plan = Arc::new(FitPlan::new(betas, opts)?);
        self.insert(key, Arc::clone(&plan));
        Ok(plan)
    }

    fn insert(&mut self, key: PlanKey, plan: Arc<FitPlan>) {
        if let Some(cap) = self.capacity {
            while self.plans.len() >= cap
                && let Some(old) = self.order.pop_front()
            {
                self.plans.remove(&old);
            }
        }
        self.order.push_back(key.clone());
        self.plans.insert(key, plan);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reuses_and_evicts() {
        let mut c = PlanCache::with_capacity(2);
        let b1 = [0.5, 0.7, 0.9];
        let b2 = [0.4, 0.7, 0.9];
        let b3 = [0.3, 0.7, 0.9];
        let o = FitOptions::default();
        let p1 = c.get(&b1, o).unwrap();
        assert!(Arc::ptr_eq(&p1, &c.get(&b1, o).unwrap()));
        c.get(&b2, o).unwrap();
        c.get(&b3, o).unwrap();
        assert_eq!(c.len(), 2);
        assert!(!Arc::ptr_eq(&p1, &c.get(&b1, o).unwrap()));
        let mut u = PlanCache::unbounded();
        for b in [b1, b2, b3] {
            u.get(&b, o).unwrap();
        }
        assert_eq!(u.len(), 3);
        assert!(c.get(&[0.5, 0.7], o).is_err());
    }
}
