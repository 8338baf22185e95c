//! Stage timings: how long each stage of a run took, in the order they ran.

use std::time::Instant;

/// The seconds each stage took, in order.
#[derive(Debug, Default)]
pub struct StageClock {
    timings_s: Vec<(&'static str, f64)>,
}

impl StageClock {
    /// Runs `stage` and records how long it took (also when it fails).
    pub fn time<T>(&mut self, stage: &'static str, run: impl FnOnce() -> T) -> T {
        let started = Instant::now();
        let out = run();
        self.record(stage, started);
        out
    }

    /// Records `stage` as having run from `started` until now.
    pub fn record(&mut self, stage: &'static str, started: Instant) {
        self.timings_s.push((stage, started.elapsed().as_secs_f64()));
    }

    /// The stages and their seconds, in the order they ran.
    pub fn into_timings(self) -> Vec<(&'static str, f64)> {
        self.timings_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_are_kept_in_order_with_their_durations() {
        let mut clock = StageClock::default();
        let value = clock.time("first", || {
            std::thread::sleep(std::time::Duration::from_millis(20));
            7
        });
        clock.record("second", Instant::now());
        let timings = clock.into_timings();
        assert_eq!(value, 7);
        assert_eq!(timings.iter().map(|t| t.0).collect::<Vec<_>>(), ["first", "second"]);
        assert!(timings[0].1 >= 0.02 && timings[1].1 < timings[0].1, "{timings:?}");
    }
}
