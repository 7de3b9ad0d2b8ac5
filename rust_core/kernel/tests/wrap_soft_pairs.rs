//! Soft pairs in the energy wrap: pulls by confidence in the stiff levels of the global-to-local
//! schedule (not in the warm-up), let go before the local fit; refused where they make no sense.

mod common;

use std::sync::Arc;

use glam::Vec3;
use springwrap_kernel::{
    Anchor, KernelError, LayoutPoint, SoftPair, TargetMesh, TargetMeshOptions, WrapSchedule,
    WrapSettings, WrapSolver,
};

const RINGS: u32 = 12;
const SEGMENTS: u32 = 48;

/// A sphere stretched by `axes` as the target, the unit sphere's band as the layout (its truth:
/// each point scaled by `axes`), four anchors on the equator at their true places.
struct Stretched {
    target: Arc<TargetMesh>,
    structure: springwrap_kernel::LayoutStructure,
    directions: Vec<Vec3>,
    truth: Vec<Vec3>,
    anchors: Vec<Anchor>,
}

fn stretched(axes: Vec3) -> Stretched {
    let (vertices, triangles) = common::uv_sphere(1.0, 64, 128);
    let vertices = vertices.into_iter().map(|v| v * axes).collect();
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let (structure, directions) = common::band_layout(Vec3::ONE, RINGS, SEGMENTS);
    let truth: Vec<Vec3> = directions.iter().map(|&d| d * axes).collect();
    let equator = RINGS / 2 * SEGMENTS;
    let quarters: Vec<u32> = (0..4).map(|q| equator + q * SEGMENTS / 4).collect();
    let anchors = common::anchors_at(&target, &truth, &quarters);
    Stretched {
        target,
        structure,
        directions,
        truth,
        anchors,
    }
}

impl Stretched {
    /// Soft pairs of confidence 1 on the top and bottom rings' quarter points, at their true
    /// places moved by `offset`.
    fn pairs(&self, offset: Vec3) -> Vec<SoftPair> {
        [1, RINGS - 1]
            .iter()
            .flat_map(|&ring| (0..4).map(move |quarter| ring * SEGMENTS + quarter * SEGMENTS / 4))
            .map(|vertex| SoftPair {
                vertex,
                target: self.truth[vertex as usize] + offset,
                confidence: 1.0,
            })
            .collect()
    }

    fn solver(&self, schedule: WrapSchedule) -> WrapSolver {
        let points = self
            .directions
            .iter()
            .map(|&p| LayoutPoint::Space(p))
            .collect();
        let settings = WrapSettings {
            schedule,
            ..WrapSettings::default()
        };
        WrapSolver::new(
            Arc::clone(&self.target),
            self.structure.clone(),
            points,
            &self.anchors,
            settings,
        )
        .unwrap()
    }

    /// The wrapped positions with `pairs`.
    fn wrap(&self, schedule: WrapSchedule, pairs: &[SoftPair]) -> Vec<Vec3> {
        let mut solver = self.solver(schedule).with_soft_pairs(pairs).unwrap();
        let report = solver.step(1000).unwrap();
        assert!(report.converged, "{report:?}");
        solver.positions().to_vec()
    }

    fn mean_error(&self, positions: &[Vec3]) -> f32 {
        positions
            .iter()
            .zip(&self.truth)
            .map(|(p, t)| p.distance(*t))
            .sum::<f32>()
            / self.truth.len() as f32
    }
}

#[test]
fn right_soft_pairs_bring_the_global_to_local_wrap_nearer_the_truth() {
    let case = stretched(Vec3::new(2.2, 1.0, 0.6));
    let without = case.mean_error(&case.wrap(WrapSchedule::GlobalToLocal, &[]));
    let with = case.mean_error(&case.wrap(WrapSchedule::GlobalToLocal, &case.pairs(Vec3::ZERO)));
    assert!(
        with < without * 0.9,
        "mean error {without} without, {with} with soft pairs"
    );
}

#[test]
fn soft_pairs_are_let_go_before_the_local_fit() {
    // Pairs off the surface by a tenth of the sphere's radius: an anchor there would end off the
    // surface; a soft pair's vertex ends on it, where the data term puts it.
    let case = stretched(Vec3::new(1.6, 1.0, 0.8));
    let pairs = case.pairs(Vec3::new(0.0, 0.0, 0.1));
    let positions = case.wrap(WrapSchedule::GlobalToLocal, &pairs);
    for pair in &pairs {
        let position = positions[pair.vertex as usize];
        let hit = case.target.closest_point(position, f32::INFINITY).unwrap();
        assert!(
            hit.distance < 0.01,
            "vertex {} ends {} off the surface",
            pair.vertex,
            hit.distance
        );
    }
}

#[test]
fn soft_pairs_do_not_pull_in_the_warm_up() {
    // The first iterations are the warm-up (the anchors alone, no data term): there a pull would
    // act as an anchor on its whole region, so the soft pairs wait for the stiff levels.
    let case = stretched(Vec3::new(2.2, 1.0, 0.6));
    let first_step = |pairs: &[SoftPair]| {
        let mut solver = case
            .solver(WrapSchedule::GlobalToLocal)
            .with_soft_pairs(pairs)
            .unwrap();
        solver.step(1).unwrap();
        solver.positions().to_vec()
    };
    let far = case.pairs(Vec3::new(0.0, 0.0, 0.3));
    assert_eq!(first_step(&[]), first_step(&far));
}

#[test]
fn the_local_schedule_takes_no_soft_pairs() {
    let case = stretched(Vec3::new(1.6, 1.0, 0.8));
    let without = case.wrap(WrapSchedule::Local, &[]);
    let with = case.wrap(WrapSchedule::Local, &case.pairs(Vec3::new(0.0, 0.0, 0.1)));
    assert_eq!(without, with);
}

#[test]
fn bad_soft_pairs_are_refused() {
    let case = stretched(Vec3::new(1.6, 1.0, 0.8));
    let good = case.pairs(Vec3::ZERO)[0];
    let anchored = SoftPair {
        vertex: case.anchors[0].vertex,
        ..good
    };
    let missing = SoftPair {
        vertex: u32::MAX,
        ..good
    };
    let unsure = SoftPair {
        confidence: 0.0,
        ..good
    };
    let nowhere = SoftPair {
        target: Vec3::NAN,
        ..good
    };
    for pairs in [
        vec![anchored],
        vec![missing],
        vec![unsure],
        vec![good, good],
    ] {
        let error = case
            .solver(WrapSchedule::Auto)
            .with_soft_pairs(&pairs)
            .err()
            .unwrap();
        assert!(
            matches!(error, KernelError::InvalidArgument { name, .. } if name == "soft pairs"),
            "{pairs:?}: {error}"
        );
    }
    let error = case
        .solver(WrapSchedule::Auto)
        .with_soft_pairs(&[nowhere])
        .err()
        .unwrap();
    assert!(matches!(error, KernelError::NonFinite { .. }), "{error}");
}
