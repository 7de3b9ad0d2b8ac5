//! The wrap: `WrapSolver` built from hostile layouts, points, anchors, curves, a plane, settings,
//! stiffness, free vertices and unreliable triangles, then stepped.

use glam::Vec3;
use proptest::prelude::*;
use proptest::sample::select;
use springwrap_kernel::{
    Anchor, AnchorTarget, CurveConstraint, FacePoint, KernelError, LayoutPoint, PlaneConstraint,
    TargetMesh, WrapSettings, WrapSolver,
};

use crate::common;
use crate::hostile::{SPECIAL_VALUES, barycentric, config, index, mild_vector, target, vector};

/// A setting: mostly the default, sometimes another value in its range, sometimes hostile.
fn setting(default: f32, high: f32) -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => Just(default),
        3 => 0.0f32..=high,
        1 => select(SPECIAL_VALUES.iter().copied().chain([-0.5, high * 1.5]).collect::<Vec<_>>()),
    ]
}

/// The settings: mostly sane (defaults or values in range), one
/// case in six hostile in any field.
fn settings() -> impl Strategy<Value = WrapSettings> {
    prop_oneof![5 => settings_with(false), 1 => settings_with(true)]
}

fn settings_with(hostile: bool) -> impl Strategy<Value = WrapSettings> {
    let defaults = WrapSettings::default();
    let weights = defaults.weights;
    let value = move |default: f32, high: f32| -> BoxedStrategy<f32> {
        if hostile {
            setting(default, high).boxed()
        } else {
            prop_oneof![3 => Just(default), 1 => 0.0f32..=high].boxed()
        }
    };
    (
        (
            value(weights.fairness, 1.0),
            value(weights.arc_length, 1.0),
            value(weights.thin_plate, 0.5),
            value(weights.constraint, 1.0),
            value(weights.folding, 1.0),
        ),
        (
            value(defaults.tolerance, 0.1).prop_map(move |t| if hostile { t } else { t.max(1e-6) }),
            value(defaults.landing_distance, 10.0),
            value(defaults.fold_tolerance, 1.5),
        ),
    )
        .prop_map(
            move |(
                (fairness, arc_length, thin_plate, constraint, folding),
                (tolerance, landing_distance, fold_tolerance),
            )| {
                let mut settings = defaults;
                settings.weights.fairness = fairness;
                settings.weights.arc_length = arc_length;
                settings.weights.thin_plate = thin_plate;
                settings.weights.constraint = constraint;
                settings.weights.folding = folding;
                settings.tolerance = tolerance;
                settings.landing_distance = landing_distance;
                settings.fold_tolerance = fold_tolerance;
                settings
            },
        )
}

/// How a layout vertex starts: where the grid puts it, snapped onto the target, on a random
/// face-point, or at a hostile position.
#[derive(Debug, Clone)]
enum Start {
    Space,
    Snapped,
    Face(u32, Vec3),
    At(Vec3),
}

fn start() -> impl Strategy<Value = Start> {
    prop_oneof![
        10 => Just(Start::Space),
        10 => Just(Start::Snapped),
        1 => (index(400), barycentric()).prop_map(|(triangle, barycentric)| Start::Face(triangle, barycentric)),
        1 => vector().prop_map(Start::At),
    ]
}

#[derive(Debug, Clone)]
enum AnchorSpec {
    Below,
    Face(u32, Vec3),
    Space(Vec3),
}

fn anchor() -> impl Strategy<Value = (u32, AnchorSpec)> {
    (
        index(25),
        prop_oneof![
            4 => Just(AnchorSpec::Below),
            1 => (prop_oneof![4 => 0u32..30, 1 => index(400)], barycentric())
                .prop_map(|(triangle, barycentric)| AnchorSpec::Face(triangle, barycentric)),
            2 => prop_oneof![6 => mild_vector(), 1 => vector()].prop_map(AnchorSpec::Space),
        ],
    )
}

/// A step count: small, zero, or beyond what one step takes.
fn steps() -> impl Strategy<Value = Vec<usize>> {
    prop::collection::vec(
        prop_oneof![
            12 => 0usize..4,
            1 => select(vec![WrapSettings::MAX_STEP_ITERATIONS + 1, usize::MAX]),
        ],
        1..3,
    )
}

#[derive(Debug, Clone)]
struct Case {
    size: u32,
    spacing: f32,
    origin: Vec3,
    starts: Vec<Start>,
    rest: Option<Vec<Option<Vec3>>>,
    anchors: Vec<(u32, AnchorSpec)>,
    curves: Vec<(Vec<u32>, Vec<Vec3>)>,
    plane: Option<(Vec<u32>, Vec3, Vec3, bool)>,
    stiffness: Option<Vec<f32>>,
    free: Option<Vec<bool>>,
    unreliable: Option<(bool, Vec<bool>)>,
    settings: WrapSettings,
    steps: Vec<usize>,
}

/// `sane` most of the time, `hostile` one time in `1 + odds`.
fn mostly<T: std::fmt::Debug + Clone + 'static>(
    odds: u32,
    sane: impl Strategy<Value = T> + 'static,
    hostile: impl Strategy<Value = T> + 'static,
) -> BoxedStrategy<T> {
    prop_oneof![odds => sane, 1 => hostile].boxed()
}

fn case() -> impl Strategy<Value = Case> {
    (1u32..4).prop_flat_map(|size| {
        let count = ((size + 1) * (size + 1)) as usize;
        let vertex = move || prop_oneof![12 => 0..count as u32, 1 => index(count)];
        let starts = mostly(
            4,
            prop::collection::vec(prop_oneof![Just(Start::Space), Just(Start::Snapped)], count),
            prop::collection::vec(start(), count),
        );
        // The rest shape: the grid (a template), the starting points (`None`: snapped points
        // may coincide), or the grid with hostile positions.
        let rest = prop_oneof![
            6 => Just(Some(vec![None; count])),
            1 => Just(None),
            1 => prop::collection::vec(prop_oneof![8 => Just(None), 1 => vector().prop_map(Some)], count)
                .prop_map(Some),
        ];
        let anchors = (
            prop::collection::vec((vertex(), anchor().prop_map(|(_, spec)| spec)), 0..4),
            prop::bool::weighted(0.85),
        )
            .prop_map(|(mut anchors, distinct)| {
                if distinct {
                    let mut seen = std::collections::HashSet::new();
                    anchors.retain(|(vertex, _)| seen.insert(*vertex));
                }
                anchors
            });
        let curves = prop::collection::vec(
            (
                mostly(6, prop::collection::vec(vertex(), 2..5), prop::collection::vec(index(count), 0..5)),
                mostly(
                    6,
                    prop::collection::vec(mild_vector(), 2..5),
                    prop::collection::vec(prop_oneof![4 => mild_vector(), 1 => vector()], 0..5),
                ),
            ),
            0..2,
        );
        let plane = prop::option::weighted(
            0.25,
            (
                prop::collection::vec(vertex(), 0..5),
                mild_vector(),
                mostly(6, mild_vector(), vector()),
                any::<bool>(),
            ),
        );
        let stiffness = prop::option::weighted(
            0.15,
            mostly(
                4,
                prop::collection::vec(0.0f32..=1.0, count),
                prop::collection::vec(prop_oneof![8 => 0.0f32..=1.0, 1 => select(SPECIAL_VALUES.to_vec())], 0..26),
            ),
        );
        let free = prop::option::weighted(
            0.15,
            mostly(
                4,
                prop::collection::vec(prop::bool::weighted(0.2), count),
                prop::collection::vec(prop::bool::weighted(0.2), 0..26),
            ),
        );
        let unreliable = prop::option::weighted(
            0.15,
            (prop::bool::weighted(0.8), prop::collection::vec(prop::bool::weighted(0.2), 0..400)),
        );
        (
            (
                Just(size),
                mostly(6, 0.1f32..0.6, select(vec![0.0, 1e-9, 1e7, f32::NAN])),
                mostly(
                    6,
                    (-0.8f32..0.8, -0.8f32..0.8, -1.2f32..1.2).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
                    vector(),
                ),
                starts,
                rest,
            ),
            (anchors, curves, plane),
            (stiffness, free, unreliable, settings(), steps()),
        )
    })
    .prop_map(|((size, spacing, origin, starts, rest), (anchors, curves, plane), (stiffness, free, unreliable, settings, steps))| Case {
        size,
        spacing,
        origin,
        starts,
        rest,
        anchors,
        curves,
        plane,
        stiffness,
        free,
        unreliable,
        settings,
        steps,
    })
}

/// Every error a wrap may return: its build's documented refusals, and a step's.
fn wrap_error(error: &KernelError) -> bool {
    matches!(
        error,
        KernelError::LengthMismatch { .. }
            | KernelError::TriangleIndexOutOfRange { .. }
            | KernelError::NonFinite { .. }
            | KernelError::CoordinateOutOfRange { .. }
            | KernelError::BeyondReach { .. }
            | KernelError::InvalidArgument { .. }
            | KernelError::Diverged { .. }
    )
}

fn build(target: &std::sync::Arc<TargetMesh>, case: &Case) -> Result<WrapSolver, KernelError> {
    let origin = case.origin - Vec3::splat(case.size as f32 * case.spacing * 0.5);
    let (structure, positions) = common::quad_layout(case.size, case.spacing, origin);
    let points: Vec<LayoutPoint> = positions
        .iter()
        .zip(&case.starts)
        .map(|(&position, start)| match start {
            Start::Space => LayoutPoint::Space(position),
            Start::Snapped => match target.closest_point(position, f32::INFINITY) {
                Some(hit) if position.is_finite() => LayoutPoint::Face(hit.face_point),
                _ => LayoutPoint::Space(position),
            },
            Start::Face(triangle, barycentric) => LayoutPoint::Face(FacePoint {
                triangle: *triangle,
                barycentric: *barycentric,
            }),
            Start::At(at) => LayoutPoint::Space(*at),
        })
        .collect();
    let rest = case.rest.as_ref().map(|rest| {
        positions
            .iter()
            .zip(rest)
            .map(|(&position, replaced)| replaced.unwrap_or(position))
            .collect()
    });
    let anchors: Vec<Anchor> = case
        .anchors
        .iter()
        .map(|(vertex, spec)| Anchor {
            vertex: *vertex,
            target: match spec {
                AnchorSpec::Below => {
                    let position = positions
                        .get(*vertex as usize)
                        .copied()
                        .unwrap_or(Vec3::ZERO);
                    match target.closest_point(
                        position.clamp(Vec3::splat(-1e6), Vec3::splat(1e6)),
                        f32::INFINITY,
                    ) {
                        Some(hit) => AnchorTarget::Face(hit.face_point),
                        None => AnchorTarget::Space(position),
                    }
                }
                AnchorSpec::Face(triangle, barycentric) => AnchorTarget::Face(FacePoint {
                    triangle: *triangle,
                    barycentric: *barycentric,
                }),
                AnchorSpec::Space(at) => AnchorTarget::Space(*at),
            },
        })
        .collect();
    let mut solver = WrapSolver::with_rest_shape(
        target.clone(),
        structure,
        points,
        rest,
        &anchors,
        case.settings,
    )?;
    let curves: Vec<CurveConstraint> = case
        .curves
        .iter()
        .map(|(layout_vertices, target)| CurveConstraint {
            layout_vertices: layout_vertices.clone(),
            target: target.clone(),
            fractions: Vec::new(),
        })
        .collect();
    solver = solver.with_curve_constraints(&curves)?;
    if let Some((vertices, point, normal, slide)) = &case.plane {
        solver = solver.with_plane_constraint(&PlaneConstraint {
            vertices: vertices.clone(),
            point: *point,
            normal: *normal,
            slide: *slide,
        })?;
    }
    if let Some((right_length, flags)) = &case.unreliable {
        let mut flags = flags.clone();
        if *right_length {
            flags.resize(target.triangles().len(), false);
        }
        solver = solver.with_unreliable_triangles(flags)?;
    }
    if let Some(stiffness) = &case.stiffness {
        solver = solver.with_vertex_stiffness(stiffness.clone())?;
    }
    if let Some(free) = &case.free {
        solver = solver.with_free_vertices(free.clone())?;
    }
    Ok(solver)
}

fn check_finite(solver: &WrapSolver, target: &TargetMesh) -> Result<(), TestCaseError> {
    prop_assert!(
        solver.positions().iter().all(|p| p.is_finite()),
        "{:?}",
        solver.positions()
    );
    for point in solver.points() {
        match point {
            LayoutPoint::Face(face_point) => {
                prop_assert!((face_point.triangle as usize) < target.triangles().len());
                prop_assert!(face_point.barycentric.is_finite(), "{face_point:?}");
            }
            LayoutPoint::Space(position) => prop_assert!(position.is_finite()),
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/wrap.txt", 800))]

    #[test]
    fn a_wrap_is_built_and_stepped_or_refused(target in target(), case in case()) {
        let mut solver = match build(&target, &case) {
            Ok(solver) => solver,
            Err(error) => {
                prop_assert!(wrap_error(&error), "{error:?}");
                return Ok(());
            }
        };
        check_finite(&solver, &target)?;
        for &iterations in &case.steps {
            match solver.step(iterations) {
                Ok(report) => {
                    prop_assert!(report.max_displacement.is_finite(), "{report:?}");
                    prop_assert!(report.mean_displacement.is_finite(), "{report:?}");
                }
                Err(error) => prop_assert!(wrap_error(&error), "{error:?}"),
            }
            // Refused or rolled back, the layout stays finite.
            check_finite(&solver, &target)?;
        }
    }
}
