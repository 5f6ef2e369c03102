//! How well `run`'s control loop keeps its 10 Hz period: each period's start lateness
//! (how long after its tick the station began the period's work) and the work's duration,
//! as histograms of 0.1 ms buckets, reported as percentiles at the end of a run.

use std::time::Duration;

use serde::Serialize;

/// Bucket width, µs.
const BUCKET_US: u64 = 100;
/// Buckets: up to 2 s; anything longer lands in the last.
const BUCKETS: usize = 20_000;

#[derive(Debug, Clone)]
struct Histogram {
    counts: Vec<u32>,
    n: u64,
    max_us: u64,
}

impl Histogram {
    fn new() -> Self {
        Self {
            counts: vec![0; BUCKETS],
            n: 0,
            max_us: 0,
        }
    }

    fn add(&mut self, d: Duration) {
        let us = d.as_micros() as u64;
        let i = ((us / BUCKET_US) as usize).min(BUCKETS - 1);
        self.counts[i] = self.counts[i].saturating_add(1);
        self.n += 1;
        self.max_us = self.max_us.max(us);
    }

    /// The upper edge of the bucket holding quantile `q`, ms.
    fn quantile_ms(&self, q: f64) -> f64 {
        let want = (q * self.n as f64).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (i, c) in self.counts.iter().enumerate() {
            seen += *c as u64;
            if seen >= want {
                return ((i as u64 + 1) * BUCKET_US) as f64 / 1000.0;
            }
        }
        0.0
    }
}

/// The loop's timing over a run.
#[derive(Debug, Clone)]
pub struct LoopTiming {
    late: Histogram,
    work: Histogram,
}

/// [`LoopTiming`] as the run's report gives it, ms.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct LoopReport {
    pub periods: u64,
    pub late_p50_ms: f64,
    pub late_p99_ms: f64,
    pub late_max_ms: f64,
    pub work_p50_ms: f64,
    pub work_p99_ms: f64,
    pub work_max_ms: f64,
}

impl Default for LoopTiming {
    fn default() -> Self {
        Self {
            late: Histogram::new(),
            work: Histogram::new(),
        }
    }
}

impl LoopTiming {
    /// One period: how late its work began, and how long it took.
    pub fn period(&mut self, late: Duration, work: Duration) {
        self.late.add(late);
        self.work.add(work);
    }

    pub fn report(&self) -> LoopReport {
        LoopReport {
            periods: self.late.n,
            late_p50_ms: self.late.quantile_ms(0.5),
            late_p99_ms: self.late.quantile_ms(0.99),
            late_max_ms: self.late.max_us as f64 / 1000.0,
            work_p50_ms: self.work.quantile_ms(0.5),
            work_p99_ms: self.work.quantile_ms(0.99),
            work_max_ms: self.work.max_us as f64 / 1000.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_come_from_the_buckets() {
        let mut t = LoopTiming::default();
        for i in 0..100u64 {
            let late = Duration::from_micros(if i == 99 { 50_000 } else { 250 });
            t.period(late, Duration::from_micros(1000 + i));
        }
        let r = t.report();
        assert_eq!(r.periods, 100);
        assert_eq!(r.late_p50_ms, 0.3);
        assert_eq!(r.late_p99_ms, 0.3);
        assert_eq!(r.late_max_ms, 50.0);
        assert_eq!(r.work_p99_ms, 1.1);
    }
}
