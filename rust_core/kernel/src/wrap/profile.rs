//! Where an energy wrap's time goes: the seconds of each phase of its setup and its iterations,
//! read from a clock the caller chooses (wall time, or the process's processor time to see what
//! the parallel phases cost in all threads). Off unless asked for: nothing is read then.

/// The phases of the energy wrap that a profile tells apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WrapPhase {
    /// Setup: the linear system's matrix, its analysis or its multigrid hierarchy.
    System,
    /// Setup: the target's smoothed normals and the rest corner normals.
    Normals,
    /// Setup: the first similarity fit and the layout's orientation against the target.
    FirstFit,
    /// Each iteration: the similarities fitted at the current positions.
    Fit,
    /// Each iteration: the rotations and the scales (or stretches) smoothed over neighbours.
    Smoothing,
    /// Each iteration: the layout normals and the closest-point queries of the data term.
    Correspondences,
    /// Each iteration: the global step's diagonal and right-hand side.
    Assembly,
    /// Each iteration: the global step's solve.
    Solve,
    /// Each iteration: the safeguard that keeps every corner from turning over.
    Safeguard,
    /// Each iteration: the energy after the step.
    Energy,
    /// The end: the points landing on the surface.
    Landing,
}

impl WrapPhase {
    /// Every phase, in the order they first run.
    pub const ALL: [Self; 11] = [
        Self::System,
        Self::Normals,
        Self::FirstFit,
        Self::Fit,
        Self::Smoothing,
        Self::Correspondences,
        Self::Assembly,
        Self::Solve,
        Self::Safeguard,
        Self::Energy,
        Self::Landing,
    ];

    /// A short lower-case name (for tables).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::System => "system",
            Self::Normals => "normals",
            Self::FirstFit => "first fit",
            Self::Fit => "fit",
            Self::Smoothing => "smoothing",
            Self::Correspondences => "correspondences",
            Self::Assembly => "assembly",
            Self::Solve => "solve",
            Self::Safeguard => "safeguard",
            Self::Energy => "energy",
            Self::Landing => "landing",
        }
    }
}

/// A clock for a profile: seconds since some fixed moment.
pub type PhaseClock = fn() -> f64;

/// Seconds spent in each [`WrapPhase`] so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimes {
    seconds: [f64; WrapPhase::ALL.len()],
}

impl PhaseTimes {
    /// The seconds spent in `phase`.
    #[must_use]
    pub fn seconds(&self, phase: WrapPhase) -> f64 {
        self.seconds[phase as usize]
    }

    /// The seconds of all phases.
    #[must_use]
    pub fn total(&self) -> f64 {
        self.seconds.iter().sum()
    }
}

/// Sums the time of phases by a clock, or does nothing without one.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Profiler {
    clock: Option<PhaseClock>,
    times: PhaseTimes,
}

impl Profiler {
    /// A profiler reading `clock` (`None`: off).
    pub(crate) fn new(clock: Option<PhaseClock>) -> Self {
        Self {
            clock,
            times: PhaseTimes::default(),
        }
    }

    /// The clock now (0 when off): where the next [`Profiler::add`] counts from.
    pub(crate) fn start(&self) -> f64 {
        self.clock.map_or(0.0, |clock| clock())
    }

    /// Adds the time since `start` to `phase`, and returns the clock now (the next phase's start).
    pub(crate) fn add(&mut self, phase: WrapPhase, start: f64) -> f64 {
        let Some(clock) = self.clock else {
            return 0.0;
        };
        let now = clock();
        self.times.seconds[phase as usize] += now - start;
        now
    }

    /// The seconds summed so far.
    pub(crate) fn times(&self) -> PhaseTimes {
        self.times
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    static TICKS: AtomicU32 = AtomicU32::new(0);

    /// A clock that moves one second each time it is read.
    fn ticking() -> f64 {
        f64::from(TICKS.fetch_add(1, Ordering::SeqCst))
    }

    #[test]
    fn a_profiler_sums_each_phase_by_its_clock_and_nothing_without_one() {
        let mut profiler = Profiler::new(Some(ticking));
        let start = profiler.start();
        let next = profiler.add(WrapPhase::Fit, start);
        profiler.add(WrapPhase::Solve, next);
        let start = profiler.start();
        profiler.add(WrapPhase::Fit, start);
        let times = profiler.times();
        assert_eq!(times.seconds(WrapPhase::Fit), 2.0);
        assert_eq!(times.seconds(WrapPhase::Solve), 1.0);
        assert_eq!(times.total(), 3.0);
        let mut off = Profiler::new(None);
        let start = off.start();
        off.add(WrapPhase::Fit, start);
        assert_eq!(off.times(), PhaseTimes::default());
        let names: std::collections::HashSet<_> = WrapPhase::ALL.iter().map(|p| p.name()).collect();
        assert_eq!(names.len(), WrapPhase::ALL.len());
    }
}
