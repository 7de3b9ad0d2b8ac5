//! Alignment: anchor fits recover known transforms, refuse bad input with typed errors, and ICP
//! brings a misaligned copy of a surface back onto it, with holes and outliers.

mod common;

use common::{Rng, grid, lumpy_egg, lumpy_egg_with_hole, uv_sphere};
use glam::{DMat3, DQuat, DVec3, Vec3};
use springwrap_kernel::{
    AlignMethod, IcpAnchors, IcpSettings, IcpUpdate, KernelError, TargetMesh, TargetMeshOptions,
    Transform, fit_transform, icp, icp_anchored,
};

/// A unit axis in a random direction.
fn random_axis(rng: &mut Rng) -> DVec3 {
    loop {
        let axis = rng.point_in_box(1.0).as_dvec3();
        if axis.length() > 0.1 && axis.length() <= 1.0 {
            return axis.normalize();
        }
    }
}

fn transform_of(linear: DMat3, translation: DVec3) -> Transform {
    let columns = linear.to_cols_array_2d();
    Transform::from_linear_translation(
        std::array::from_fn(|row| std::array::from_fn(|column| columns[column][row])),
        translation,
    )
}

/// Largest entry difference between two transforms' linear parts and translations, each relative
/// to the expected part's own size.
fn transform_error(found: &Transform, expected: &Transform) -> f64 {
    let linear_size = expected
        .linear()
        .iter()
        .flatten()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    let linear_error = (0..3)
        .flat_map(|r| (0..3).map(move |c| (r, c)))
        .map(|(r, c)| (found.rows[r][c] - expected.rows[r][c]).abs())
        .fold(0.0, f64::max)
        / linear_size;
    let translation_error = (found.translation() - expected.translation()).length()
        / expected.translation().length().max(1.0);
    linear_error.max(translation_error)
}

fn random_points(rng: &mut Rng, count: usize) -> Vec<Vec3> {
    (0..count).map(|_| rng.point_in_box(1.0)).collect()
}

/// Rotation angles to try, including 0 and the ill-conditioned neighbourhood of 180°.
const ANGLES: [f64; 7] = [
    0.0,
    0.3,
    1.5,
    2.9,
    std::f64::consts::PI - 1e-4,
    std::f64::consts::PI - 1e-7,
    std::f64::consts::PI,
];

#[test]
fn similarity_and_rigid_are_recovered_from_exact_pairs() {
    let mut rng = Rng::new(5);
    let mut worst = 0.0f64;
    for (case, &angle) in ANGLES.iter().cycle().take(35).enumerate() {
        let rotation = DQuat::from_axis_angle(random_axis(&mut rng), angle);
        // Scales spread log-uniformly over 0.1 .. 10.
        let scale = 10f64.powf(f64::from(rng.range(-1.0, 1.0)));
        let translation = rng.point_in_box(5.0).as_dvec3();
        let expected = transform_of(DMat3::from_quat(rotation) * scale, translation);
        let source = random_points(&mut rng, 4 + case % 7);
        let target = expected.apply_all(&source);
        let found = fit_transform(&source, &target, AlignMethod::Similarity, None).unwrap();
        let error = transform_error(&found, &expected);
        assert!(
            error < 1e-5,
            "case {case}: angle {angle}, scale {scale}: error {error}"
        );
        worst = worst.max(error);

        let rigid_expected = transform_of(DMat3::from_quat(rotation), translation);
        let rigid_target = rigid_expected.apply_all(&source);
        let found = fit_transform(&source, &rigid_target, AlignMethod::Rigid, None).unwrap();
        let error = transform_error(&found, &rigid_expected);
        assert!(
            error < 1e-5,
            "rigid case {case}: angle {angle}: error {error}"
        );
    }
    println!("worst similarity error {worst:e}");
}

#[test]
fn affine_is_recovered_from_exact_pairs() {
    let mut rng = Rng::new(11);
    for case in 0..30 {
        // A random linear map kept away from singular: identity-scaled plus a random shear.
        let scale = 10f64.powf(f64::from(rng.range(-1.0, 1.0)));
        let shear = DMat3::from_cols(
            rng.point_in_box(0.4).as_dvec3(),
            rng.point_in_box(0.4).as_dvec3(),
            rng.point_in_box(0.4).as_dvec3(),
        );
        let rotation = DMat3::from_quat(DQuat::from_axis_angle(
            random_axis(&mut rng),
            ANGLES[case % ANGLES.len()],
        ));
        let stretch = DMat3::from_diagonal(DVec3::new(1.0, 0.5, 2.0));
        let linear = rotation * (stretch + shear) * scale;
        let expected = transform_of(linear, rng.point_in_box(5.0).as_dvec3());
        let source = random_points(&mut rng, 4 + case % 6);
        let target = expected.apply_all(&source);
        let found = fit_transform(&source, &target, AlignMethod::Affine, None).unwrap();
        let error = transform_error(&found, &expected);
        assert!(error < 1e-5, "case {case}: error {error}");
    }
}

#[test]
fn weights_pick_out_the_pairs_that_count() {
    // Three exact pairs plus a wrong one of weight zero: the wrong one must not move the fit.
    let mut rng = Rng::new(2);
    let expected = transform_of(
        DMat3::from_quat(DQuat::from_rotation_z(0.7)) * 2.0,
        DVec3::new(1.0, 2.0, 3.0),
    );
    let source = random_points(&mut rng, 4);
    let mut target = expected.apply_all(&source);
    target[3] += Vec3::new(5.0, 0.0, 0.0);
    let weights = [1.0, 1.0, 1.0, 0.0];
    let found = fit_transform(&source, &target, AlignMethod::Similarity, Some(&weights)).unwrap();
    assert!(transform_error(&found, &expected) < 1e-5);
    let unweighted = fit_transform(&source, &target, AlignMethod::Similarity, None).unwrap();
    assert!(transform_error(&unweighted, &expected) > 1e-2);
}

#[test]
fn mirrored_pairs_never_give_a_reflection() {
    let mut rng = Rng::new(3);
    for case in 0..20 {
        let source = random_points(&mut rng, 6);
        let rotation = DMat3::from_quat(DQuat::from_axis_angle(
            random_axis(&mut rng),
            ANGLES[case % ANGLES.len()],
        ));
        let mirror = DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0));
        let target = transform_of(rotation * mirror * 1.5, DVec3::ZERO).apply_all(&source);
        for method in [AlignMethod::Rigid, AlignMethod::Similarity] {
            let found = fit_transform(&source, &target, method, None).unwrap();
            assert!(
                found.determinant() > 0.0,
                "case {case} {method:?}: a reflection"
            );
            // The linear part is a positive multiple of a rotation: LᵀL = s² I.
            let linear = DMat3::from_cols_array_2d(&found.linear()).transpose();
            let gram = linear.transpose() * linear;
            let scale_squared = gram.x_axis.x;
            let deviation = (gram - DMat3::IDENTITY * scale_squared)
                .abs()
                .to_cols_array();
            assert!(
                deviation
                    .iter()
                    .all(|&value| value < 1e-9 * scale_squared.max(1.0))
            );
        }
        // The affine fit may mirror: that is what it was asked to find.
        let affine = fit_transform(&source, &target, AlignMethod::Affine, None).unwrap();
        assert!(affine.determinant() < 0.0);
    }
}

#[test]
fn bad_anchors_give_typed_errors() {
    let tetrahedron = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    let fit =
        |source: &[Vec3], target: &[Vec3], method| fit_transform(source, target, method, None);

    assert_eq!(
        fit(&tetrahedron[..2], &tetrahedron[..2], AlignMethod::Rigid),
        Err(KernelError::TooFewPairs {
            what: "rigid fit",
            given: 2,
            needed: 3
        })
    );
    assert!(matches!(
        fit(&tetrahedron[..3], &tetrahedron[..3], AlignMethod::Affine),
        Err(KernelError::TooFewPairs {
            needed: 4,
            given: 3,
            ..
        })
    ));
    // Zero-weight pairs do not count towards the minimum.
    assert!(matches!(
        fit_transform(
            &tetrahedron,
            &tetrahedron,
            AlignMethod::Similarity,
            Some(&[1.0, 1.0, 0.0, 0.0])
        ),
        Err(KernelError::TooFewPairs { given: 2, .. })
    ));

    let square = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
    let error = fit(&square, &tetrahedron, AlignMethod::Affine).unwrap_err();
    assert_eq!(error, KernelError::CoplanarAnchors { count: 4 });
    assert_eq!(
        error.to_string(),
        "the 4 anchors are coplanar: an affine fit needs 4 not in one plane"
    );
    // Six anchors on a tilted plane: f32 rounding leaves them a hair off it, which must still
    // count as coplanar rather than give a wild fit.
    let tilted: Vec<Vec3> = [
        (0.1, 0.2),
        (0.9, 0.3),
        (0.4, 0.8),
        (0.7, 0.7),
        (0.2, 0.6),
        (0.5, 0.1),
    ]
    .iter()
    .map(|&(x, y)| Vec3::new(x, y, 1.0 - 0.3 * x - 0.7 * y))
    .collect();
    let spread: Vec<Vec3> = tilted.iter().map(|&point| point * 2.0 + Vec3::Z).collect();
    assert_eq!(
        fit(&tilted, &spread, AlignMethod::Affine),
        Err(KernelError::CoplanarAnchors { count: 6 })
    );
    // Coplanar anchors are fine for a similarity.
    assert!(fit(&square, &square, AlignMethod::Similarity).is_ok());

    let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
    assert_eq!(
        fit(&line, &tetrahedron[..3], AlignMethod::Rigid),
        Err(KernelError::CollinearAnchors {
            side: "source",
            count: 3
        })
    );
    // Target anchors on one line leave the rotation about that line free too.
    assert_eq!(
        fit(&tetrahedron[..3], &line, AlignMethod::Similarity),
        Err(KernelError::CollinearAnchors {
            side: "target",
            count: 3
        })
    );

    let point = [Vec3::ONE; 4];
    assert_eq!(
        fit(&point, &tetrahedron, AlignMethod::Similarity),
        Err(KernelError::CoincidentAnchors { side: "source" })
    );
    assert_eq!(
        fit(&tetrahedron, &point, AlignMethod::Affine),
        Err(KernelError::CoincidentAnchors { side: "target" })
    );

    let mut bad = tetrahedron;
    bad[2].y = f32::NAN;
    assert_eq!(
        fit(&tetrahedron, &bad, AlignMethod::Rigid),
        Err(KernelError::NonFinite {
            what: "target anchor",
            index: 2
        })
    );
    bad[2].y = f32::INFINITY;
    assert!(matches!(
        fit(&bad, &tetrahedron, AlignMethod::Rigid),
        Err(KernelError::NonFinite {
            what: "source anchor",
            index: 2
        })
    ));

    assert!(matches!(
        fit(&tetrahedron, &tetrahedron[..3], AlignMethod::Rigid),
        Err(KernelError::LengthMismatch {
            first: 4,
            second: 3,
            ..
        })
    ));
    assert!(matches!(
        fit_transform(
            &tetrahedron,
            &tetrahedron,
            AlignMethod::Rigid,
            Some(&[1.0; 3])
        ),
        Err(KernelError::LengthMismatch {
            first: 4,
            second: 3,
            ..
        })
    ));
    assert!(matches!(
        fit_transform(
            &tetrahedron,
            &tetrahedron,
            AlignMethod::Rigid,
            Some(&[1.0, -1.0, 1.0, 1.0])
        ),
        Err(KernelError::InvalidArgument {
            name: "weights",
            ..
        })
    ));
    assert!(matches!(
        fit_transform(
            &tetrahedron,
            &tetrahedron,
            AlignMethod::Rigid,
            Some(&[1.0, f32::NAN, 1.0, 1.0])
        ),
        Err(KernelError::NonFinite {
            what: "weight",
            index: 1
        })
    ));
}

// ICP ------------------------------------------------------------------------------------------

/// Egg radius; its bounding-box diagonal is about 2.8 × this.
const RADIUS: f32 = 2.0;

/// Points spread over a surface: every vertex and every triangle centroid.
fn surface_samples(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut points = vertices.to_vec();
    points.extend(triangles.iter().map(|triangle| {
        triangle
            .iter()
            .map(|&corner| vertices[corner as usize])
            .sum::<Vec3>()
            / 3.0
    }));
    points
}

fn diagonal(mesh: &TargetMesh) -> f64 {
    let (low, high) = mesh.bounding_box();
    f64::from((high - low).length())
}

/// The stated misalignment: 10° about a tilted axis and a shift of 5 % of the target's size
/// (times `scale`, 1 for a rigid one).
fn misalignment(size: f64, scale: f64) -> Transform {
    let rotation =
        DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 10f64.to_radians());
    let shift = DVec3::new(1.0, -1.0, 1.0).normalize() * 0.05 * size;
    transform_of(DMat3::from_quat(rotation) * scale, shift)
}

/// Largest distance between where `found` and `exact` take the points.
fn placement_error(found: &Transform, exact: &[Vec3], points: &[Vec3]) -> f64 {
    points
        .iter()
        .zip(exact)
        .map(|(&point, &exact)| found.apply_f64(point.as_dvec3()).distance(exact.as_dvec3()))
        .fold(0.0, f64::max)
}

/// Moves `points` off by `misalignment` and returns them: ICP must undo it.
fn misaligned(points: &[Vec3], misalignment: &Transform) -> Vec<Vec3> {
    misalignment.apply_all(points)
}

#[test]
fn icp_converges_on_a_closed_target() {
    let (vertices, triangles) = lumpy_egg(RADIUS, 24, 32);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let size = diagonal(&mesh);
    let source = misaligned(&samples, &misalignment(size, 1.0));

    let report = icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap();
    println!("closed: diagonal {size}, {report:?}");
    assert!(report.converged, "{report:?}");
    assert!(report.rms_before > 0.02 * size);
    assert!(report.rms_after < 1e-5 * size, "{report:?}");
    assert!(placement_error(&report.transform, &samples, &source) < 1e-4 * size);
    assert!(report.pairs_used >= samples.len() * 89 / 100);
}

#[test]
fn icp_leaves_free_directions_alone() {
    // A sphere does not fix its spin: ICP must undo the shift and not wander about its centre.
    let (vertices, triangles) = uv_sphere(RADIUS, 48, 64);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let size = diagonal(&mesh);
    let shift = transform_of(DMat3::IDENTITY, DVec3::new(0.03, -0.02, 0.01) * size);
    let source = misaligned(&samples, &shift);
    let report = icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap();
    println!("sphere: {report:?}");
    assert!(report.converged, "{report:?}");
    assert!(report.rms_after < 1e-4 * size, "{report:?}");
    let spin = (0..3)
        .flat_map(|r| (0..3).map(move |c| (r, c)))
        .map(|(r, c)| (report.transform.rows[r][c] - f64::from(u8::from(r == c))).abs())
        .fold(0.0, f64::max);
    assert!(spin < 1e-3, "the sphere spun: {spin}, {report:?}");
    let back = report.transform.translation() + shift.translation();
    assert!(back.length() < 1e-3 * size, "{report:?}");
}

#[test]
fn icp_settles_on_a_plane_it_can_slide_along() {
    // On a flat grid, sliding and turning in the plane change nothing: the normal equations are
    // singular there, and only the damping lets the step solve at all.
    let (vertices, triangles) = grid(20);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let lift = transform_of(
        DMat3::from_quat(DQuat::from_rotation_x(3f64.to_radians())),
        DVec3::new(0.0, 0.0, 0.5),
    );
    let source = misaligned(&samples, &lift);
    let report = icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap();
    println!("plane: {report:?}");
    assert!(report.converged && report.iterations > 0, "{report:?}");
    assert!(report.rms_after < 1e-6, "{report:?}");
    let landed = report.transform.apply_all(&source);
    assert!(landed.iter().all(|point| point.z.abs() < 1e-5));
}

#[test]
fn icp_reports_an_unfinished_run() {
    let (vertices, triangles) = lumpy_egg(RADIUS, 24, 32);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let size = diagonal(&mesh);
    let source = misaligned(&samples, &misalignment(size, 1.0));
    let settings = IcpSettings {
        max_iterations: 1,
        ..IcpSettings::default()
    };
    let report = icp(&mesh, &source, Transform::IDENTITY, settings).unwrap();
    assert_eq!(report.iterations, 1);
    assert!(!report.converged, "{report:?}");
    assert!(report.rms_after < 0.5 * report.rms_before, "{report:?}");
    assert!(report.rms_after > 1e-5 * size, "{report:?}");
    // Zero iterations: the initial transform comes back untouched.
    let settings = IcpSettings {
        max_iterations: 0,
        ..IcpSettings::default()
    };
    let report = icp(&mesh, &source, Transform::IDENTITY, settings).unwrap();
    assert_eq!(report.transform, Transform::IDENTITY);
    assert_eq!(report.rms_after, report.rms_before);
}

#[test]
fn icp_similarity_recovers_a_scale() {
    let (vertices, triangles) = lumpy_egg(RADIUS, 24, 32);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let size = diagonal(&mesh);
    let source = misaligned(&samples, &misalignment(size, 1.05));
    let settings = IcpSettings {
        update: IcpUpdate::Similarity,
        ..IcpSettings::default()
    };
    let report = icp(&mesh, &source, Transform::IDENTITY, settings).unwrap();
    println!("similarity: {report:?}");
    assert!(report.converged, "{report:?}");
    assert!(report.rms_after < 1e-5 * size, "{report:?}");
    assert!(placement_error(&report.transform, &samples, &source) < 1e-4 * size);

    // A rigid update cannot undo the 5 % scale.
    let rigid = icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap();
    assert!(rigid.rms_after > 1e-3 * size, "{rigid:?}");
}

#[test]
fn icp_converges_on_a_target_with_a_hole() {
    // The source is the whole egg; the target lost its top cap, so the cap's points have no
    // partner but the hole's rim.
    let (full_vertices, full_triangles) = lumpy_egg(RADIUS, 24, 32);
    let samples = surface_samples(&full_vertices, &full_triangles);
    let (vertices, triangles) = lumpy_egg_with_hole(RADIUS, 24, 32, 0.35 * RADIUS);
    let removed = full_triangles.len() - triangles.len();
    assert!(
        removed > full_triangles.len() / 20,
        "the hole is {removed} triangles"
    );
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    assert!(!mesh.boundary_edges().is_empty());
    let size = diagonal(&mesh);
    let source = misaligned(&samples, &misalignment(size, 1.0));

    let report = icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap();
    println!("holed: {report:?}");
    assert!(report.converged, "{report:?}");
    assert!(report.rms_after < 1e-5 * size, "{report:?}");
    assert!(placement_error(&report.transform, &samples, &source) < 1e-4 * size);
}

#[test]
fn trimming_makes_outliers_harmless() {
    let (vertices, triangles) = lumpy_egg(RADIUS, 24, 32);
    let mut samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let size = diagonal(&mesh);
    // 5 % outliers: points pushed a quarter of the size away from the surface, all one way.
    let mut rng = Rng::new(9);
    let clean = samples.len();
    for _ in 0..clean / 20 {
        let point = samples[rng.below(clean)];
        samples.push(point + Vec3::new(1.0, 0.3, 0.2) * (0.25 * size as f32));
    }
    let source = misaligned(&samples, &misalignment(size, 1.0));

    let trimmed = icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap();
    println!("trimmed: {trimmed:?}");
    let error = placement_error(&trimmed.transform, &samples[..clean], &source[..clean]);
    assert!(error < 1e-4 * size, "trimmed: error {error}, {trimmed:?}");

    let untrimmed_settings = IcpSettings {
        trim_fraction: 0.0,
        ..IcpSettings::default()
    };
    let untrimmed = icp(&mesh, &source, Transform::IDENTITY, untrimmed_settings).unwrap();
    let error = placement_error(&untrimmed.transform, &samples[..clean], &source[..clean]);
    println!("untrimmed: error {error}, {untrimmed:?}");
    assert!(
        error > 1e-3 * size,
        "the outliers should pull an untrimmed fit off"
    );
}

#[test]
fn icp_refuses_bad_input() {
    let (vertices, triangles) = lumpy_egg(RADIUS, 8, 12);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let run = |source: &[Vec3], settings| icp(&mesh, source, Transform::IDENTITY, settings);

    for trim_fraction in [-0.1, 1.0, f32::NAN] {
        let settings = IcpSettings {
            trim_fraction,
            ..IcpSettings::default()
        };
        assert!(matches!(
            run(&samples, settings),
            Err(KernelError::InvalidArgument {
                name: "trim_fraction",
                ..
            })
        ));
    }
    let settings = IcpSettings {
        max_distance: 0.0,
        ..IcpSettings::default()
    };
    assert!(matches!(
        run(&samples, settings),
        Err(KernelError::InvalidArgument {
            name: "max_distance",
            ..
        })
    ));
    let mut bad = samples.clone();
    bad[7].z = f32::NAN;
    assert_eq!(
        run(&bad, IcpSettings::default()),
        Err(KernelError::NonFinite {
            what: "source point",
            index: 7
        })
    );
    let mut initial = Transform::IDENTITY;
    initial.rows[1][3] = f64::INFINITY;
    assert!(matches!(
        icp(&mesh, &samples, initial, IcpSettings::default()),
        Err(KernelError::InvalidArgument {
            name: "initial",
            ..
        })
    ));
    assert_eq!(
        run(&samples[..5], IcpSettings::default()),
        Err(KernelError::TooFewPairs {
            what: "ICP",
            given: 5,
            needed: 6
        })
    );
    // Every point farther than the distance limit: no pairs at all.
    let far: Vec<Vec3> = samples
        .iter()
        .map(|&point| point + Vec3::splat(100.0))
        .collect();
    let settings = IcpSettings {
        max_distance: 1.0,
        ..IcpSettings::default()
    };
    assert!(matches!(
        run(&far, settings),
        Err(KernelError::TooFewPairs { given: 0, .. })
    ));
}

#[test]
fn anchored_icp_follows_the_anchors_where_the_surface_leaves_it_free() {
    // On a plane, ICP alone cannot tell where along the plane the grid belongs; anchors can.
    let (vertices, triangles) = grid(24);
    let samples: Vec<Vec3> = surface_samples(&vertices, &triangles)
        .into_iter()
        .filter(|point| (8.0..16.0).contains(&point.x) && (8.0..16.0).contains(&point.y))
        .collect();
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let lift = transform_of(DMat3::IDENTITY, DVec3::new(0.0, 0.0, 0.3));
    let source = misaligned(&samples, &lift);
    let anchor_source = [
        source[0],
        source[source.len() / 2],
        source[source.len() - 1],
    ];
    let slide = Vec3::new(2.5, -1.0, 0.0);
    let anchor_target: Vec<Vec3> = [
        samples[0],
        samples[samples.len() / 2],
        samples[samples.len() - 1],
    ]
    .iter()
    .map(|&point| point + slide)
    .collect();
    let anchors = IcpAnchors {
        source: &anchor_source,
        target: &anchor_target,
        weight: 1.0,
    };
    let report = icp_anchored(
        &mesh,
        &source,
        anchors,
        Transform::IDENTITY,
        IcpSettings::default(),
    )
    .unwrap();
    assert!(report.converged, "{report:?}");
    let landed = report.transform.apply_all(&source);
    assert!(
        landed.iter().all(|point| point.z.abs() < 1e-4),
        "{report:?}"
    );
    for (found, wanted) in report
        .transform
        .apply_all(&anchor_source)
        .iter()
        .zip(&anchor_target)
    {
        assert!(found.distance(*wanted) < 1e-4, "{found} vs {wanted}");
    }
    // Plain ICP (or weight 0) lands on the plane but does not slide.
    for weight in [0.0, f64::NAN] {
        let report = if weight.is_nan() {
            icp(&mesh, &source, Transform::IDENTITY, IcpSettings::default()).unwrap()
        } else {
            let anchors = IcpAnchors { weight, ..anchors };
            icp_anchored(
                &mesh,
                &source,
                anchors,
                Transform::IDENTITY,
                IcpSettings::default(),
            )
            .unwrap()
        };
        let moved = report.transform.apply_all(&anchor_source);
        assert!(moved[0].distance(anchor_target[0]) > 2.0, "{report:?}");
    }
}

#[test]
fn anchored_icp_weighs_the_anchors_against_the_surface() {
    // The egg is scaled 5 % about its centre and the anchors say so; a rigid ICP cannot scale, so
    // the heavier the anchors, the nearer the anchored points get to their targets.
    let (vertices, triangles) = lumpy_egg(RADIUS, 24, 32);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let picks = [
        0,
        samples.len() / 3,
        2 * samples.len() / 3,
        samples.len() - 1,
    ];
    let anchor_source: Vec<Vec3> = picks.iter().map(|&index| samples[index]).collect();
    let anchor_target: Vec<Vec3> = anchor_source
        .iter()
        .map(|&point| point * 1.05 + Vec3::X * 0.2)
        .collect();
    let mut previous = f32::INFINITY;
    for weight in [0.0, 0.1, 1.0, 10.0] {
        let anchors = IcpAnchors {
            source: &anchor_source,
            target: &anchor_target,
            weight,
        };
        let report = icp_anchored(
            &mesh,
            &samples,
            anchors,
            Transform::IDENTITY,
            IcpSettings::default(),
        )
        .unwrap();
        let residual: f32 = report
            .transform
            .apply_all(&anchor_source)
            .iter()
            .zip(&anchor_target)
            .map(|(found, wanted)| found.distance(*wanted))
            .sum();
        assert!(
            residual < previous,
            "weight {weight}: {residual} after {previous}"
        );
        previous = residual;
    }
}

#[test]
fn anchored_icp_refuses_bad_anchors() {
    let (vertices, triangles) = grid(4);
    let samples = surface_samples(&vertices, &triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let one = [Vec3::ZERO];
    let two = [Vec3::ZERO, Vec3::X];
    let run = |anchors: IcpAnchors<'_>| {
        icp_anchored(
            &mesh,
            &samples,
            anchors,
            Transform::IDENTITY,
            IcpSettings::default(),
        )
    };
    assert!(matches!(
        run(IcpAnchors {
            source: &one,
            target: &two,
            weight: 1.0
        }),
        Err(KernelError::LengthMismatch { .. })
    ));
    assert!(matches!(
        run(IcpAnchors {
            source: &one,
            target: &[Vec3::NAN],
            weight: 1.0
        }),
        Err(KernelError::NonFinite {
            what: "anchor target",
            index: 0
        })
    ));
    assert!(matches!(
        run(IcpAnchors {
            source: &one,
            target: &one,
            weight: -1.0
        }),
        Err(KernelError::InvalidArgument {
            name: "anchor_weight",
            ..
        })
    ));
}
