//! The wrap is bit-deterministic: the same wrap run in thread pools of different sizes gives the
//! same positions, to the bit (no parallel sum whose grouping follows the threads or their
//! timing).

mod common;

use glam::Vec3;
use springwrap_kernel::{LayoutPoint, StepReport, WrapSchedule, WrapSettings, WrapSolver};

/// A band of `rings` x `segments` quads wrapped with `schedule` onto the unit sphere stretched
/// by (1.6, 1, 0.8), four anchors on its equator at their true places: the positions as bits,
/// and the last report.
fn wrap_band(schedule: WrapSchedule, rings: u32, segments: u32) -> (Vec<[u32; 3]>, StepReport) {
    let axes = Vec3::new(1.6, 1.0, 0.8);
    let (target, structure, directions, _, anchors) = common::stretched_band(axes, rings, segments);
    let points = directions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let settings = WrapSettings {
        schedule,
        ..WrapSettings::default()
    };
    let mut solver = WrapSolver::new(target, structure, points, &anchors, settings).unwrap();
    let report = solver.step(1000).unwrap();
    let bits = solver
        .positions()
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect();
    (bits, report)
}

#[test]
fn the_same_wrap_in_pools_of_one_two_and_three_threads_is_identical_to_the_bit() {
    // 19,000 points: every parallel pass over the points or the terms is cut into pieces, as
    // many as the pool has threads (and more where a thread steals work), so a sum whose
    // grouping followed the pieces would differ here in its last bits.
    // The global-to-local schedule: the local one's passes and its own smoothing solves.
    for schedule in [WrapSchedule::GlobalToLocal] {
        let runs: Vec<(Vec<[u32; 3]>, StepReport)> = [1, 2, 3]
            .into_iter()
            .map(|threads| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| wrap_band(schedule, 72, 256))
            })
            .collect();
        let (first, report) = &runs[0];
        assert!(report.converged, "{report:?}");
        for (threads, (positions, other)) in [2, 3].into_iter().zip(&runs[1..]) {
            let differing = positions.iter().zip(first).filter(|(a, b)| a != b).count();
            assert_eq!(
                differing, 0,
                "{schedule:?}: {differing} points differ with {threads} threads from one thread"
            );
            assert_eq!(
                other.energy.to_bits(),
                report.energy.to_bits(),
                "{schedule:?}: the energy with {threads} threads"
            );
        }
    }
}
