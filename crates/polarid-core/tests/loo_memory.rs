//! Leave-one-out over 20,000 labelled estimates stays linear in memory (issue 19: it
//! took 6.1 GB, n² neighbours, before). A counting allocator records the peak of live
//! heap bytes during the evaluation; n² neighbours would be 20,000² × 16 bytes = 6.4 GB.
//!
//! The evaluation takes time n²: the quick suite runs 5,000 items (n² neighbours: 400 MB)
//! against the same bound per item (3.3 KB: 16 MiB), `POLARID_FULL=1` the 20,000 (64
//! MiB). (polarid-core has no test dependency on the test kit: the flag is read here.)

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use polarid_core::FitStatus;
use polarid_core::classify::{ClassifierConfig, Cov2, Estimate, Labelled, leave_one_out};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn leave_one_out_of_20000_items_is_linear_in_memory() {
    let full = std::env::var_os("POLARID_FULL").is_some_and(|v| !v.is_empty() && v != "0");
    let n: usize = if full { 20_000 } else { 5_000 };
    let classes = ["aluminum", "copper", "gold", "paint"];
    let items: Vec<Labelled> = (0..n)
        .map(|i| {
            let c = i % classes.len();
            // A deterministic spread around each class centre.
            let u = ((i as f64) * 0.618_033_988_75).fract() - 0.5;
            let v = ((i as f64) * 0.414_213_562_37).fract() - 0.5;
            Labelled {
                target: format!("T{i}"),
                class: classes[c].to_string(),
                estimate: Estimate {
                    n: 0.5 + c as f64 * 0.5 + 0.2 * u,
                    k: 1.0 + c as f64 * 0.8 + 0.2 * v,
                    cov: Cov2::from_se(0.05, 0.05, 0.1),
                    fit_status: FitStatus::Ok,
                }
                .into(),
                source: format!("fits.csv:{i}"),
            }
        })
        .collect();
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let ev = leave_one_out(&items, ClassifierConfig::set(0.95)).unwrap();
    let peak = PEAK.load(Ordering::Relaxed) - before;
    assert_eq!(ev.items.len(), n);
    // The four classes are well separated: nearly everything is right.
    assert!(ev.accuracy > 0.95, "{}", ev.accuracy);
    // Linear: a few hundred bytes per item (decisions, names); n² would be 6.4 GB at
    // 20,000 items, 400 MB at 5,000. The bound: 64 MiB for 20,000 items.
    println!("peak heap during leave-one-out: {peak} bytes for {n} items");
    assert!(
        peak < (64 << 20) / 20_000 * n,
        "peak heap during leave-one-out: {peak} bytes for {n} items"
    );
}
