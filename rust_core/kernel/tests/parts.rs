//! Parts that follow the layout's surface: separate pieces found, moved by the surface's motion
//! (rigid pieces keep their shape, soft ones bend), and bad inputs refused.

use glam::{DQuat, DVec3};
use springwrap_kernel::{FollowSettings, KernelError, SurfaceFollower, connected_pieces};

/// Points of a sphere (Fibonacci spiral) of `radius` about `centre`.
fn sphere(count: usize, radius: f64, centre: DVec3) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5.0_f64.sqrt());
    (0..count)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let ring = (1.0 - y * y).sqrt();
            let angle = golden * i as f64;
            centre + radius * DVec3::new(ring * angle.cos(), y, ring * angle.sin())
        })
        .collect()
}

fn centroid(points: &[DVec3]) -> DVec3 {
    points.iter().sum::<DVec3>() / points.len() as f64
}

fn similarity(point: DVec3) -> DVec3 {
    DVec3::new(0.3, -0.2, 0.5)
        + 1.2 * (DQuat::from_rotation_y(0.4) * DQuat::from_rotation_x(-0.2) * point)
}

#[test]
fn separate_pieces_are_numbered_by_their_lowest_vertex() {
    // Vertices 0-1-3 joined, 2 alone, 4-5 joined.
    let pieces = connected_pieces(6, &[[3, 1], [1, 0], [5, 4]]).unwrap();
    assert_eq!(pieces, vec![0, 0, 1, 0, 2, 2]);
    assert!(matches!(
        connected_pieces(3, &[[0, 3]]),
        Err(KernelError::LayoutIndexOutOfRange { vertex: 3, .. })
    ));
}

#[test]
fn a_similarity_of_the_surface_carries_rigid_and_soft_parts_exactly() {
    let surface = sphere(400, 1.0, DVec3::ZERO);
    let parts = [
        sphere(60, 0.3, DVec3::new(0.2, 0.1, 0.0)),
        sphere(60, 0.2, DVec3::new(-0.4, 0.0, 0.3)),
    ]
    .concat();
    let pieces: Vec<u32> = (0..120).map(|i| u32::from(i >= 60)).collect();
    let settings = FollowSettings {
        scale: true,
        ..FollowSettings::default()
    };
    let follower =
        SurfaceFollower::new(&surface, &parts, &pieces, &[true, false], settings).unwrap();
    let moved = follower
        .apply(&surface.iter().map(|&p| similarity(p)).collect::<Vec<_>>())
        .unwrap();
    for (&rest, &now) in parts.iter().zip(&moved) {
        assert!(
            now.distance(similarity(rest)) < 1e-9,
            "{now} against {}",
            similarity(rest)
        );
    }
}

#[test]
fn a_sphere_inside_a_deformed_sphere_moves_with_it_and_keeps_its_radius() {
    let surface = sphere(800, 1.0, DVec3::ZERO);
    // An eyeball just under the surface (as behind the lids).
    let centre = DVec3::new(0.7, 0.1, 0.0);
    let eye = sphere(200, 0.15, centre);
    // A smooth bend and stretch of the surface, then a turn and a shift.
    let deform = |p: DVec3| {
        let bent = DVec3::new(p.x * 1.05, p.y + 0.05 * p.x * p.x, p.z * 0.98);
        similarity(bent)
    };
    let surface_now: Vec<DVec3> = surface.iter().map(|&p| deform(p)).collect();
    let settings = FollowSettings {
        scale: true,
        ..FollowSettings::default()
    };
    let follower =
        SurfaceFollower::new(&surface, &eye, &vec![0; eye.len()], &[true], settings).unwrap();
    let moved = follower.apply(&surface_now).unwrap();
    let moved_centre = centroid(&moved);
    // Each point's distance from the centre changes by one factor: the sphere keeps its shape.
    let ratios: Vec<f64> = moved
        .iter()
        .zip(&eye)
        .map(|(p, r)| p.distance(moved_centre) / r.distance(centroid(&eye)))
        .collect();
    let (low, high) = ratios
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(l, h), &r| (l.min(r), h.max(r)));
    assert!((high - low) / high < 1e-9, "radius ratios {low} … {high}");
    // It goes where the deformation takes the space around it (within a quarter of its radius; left
    // where it was, it would be more than two radii away).
    assert!(deform(centre).distance(centre) > 2.0 * 0.15);
    assert!(
        moved_centre.distance(deform(centre)) < 0.25 * 0.15,
        "{moved_centre} against {}",
        deform(centre)
    );
    // A soft piece bends with the surface: about as close to the deformation as the rigid fit, far closer than
    // where it was.
    let soft =
        SurfaceFollower::new(&surface, &eye, &vec![0; eye.len()], &[false], settings).unwrap();
    let soft_moved = soft.apply(&surface_now).unwrap();
    let error = |points: &[DVec3]| {
        points
            .iter()
            .zip(&eye)
            .map(|(p, &r)| p.distance(deform(r)))
            .sum::<f64>()
    };
    assert!(
        error(&soft_moved) < error(&moved) * 1.5,
        "{} against {}",
        error(&soft_moved),
        error(&moved)
    );
    assert!(error(&soft_moved) < 0.25 * error(&eye));
}

#[test]
fn without_scale_a_rigid_part_keeps_its_size() {
    let surface = sphere(300, 1.0, DVec3::ZERO);
    let eye = sphere(50, 0.2, DVec3::ZERO);
    let follower =
        SurfaceFollower::new(&surface, &eye, &[0; 50], &[true], FollowSettings::default()).unwrap();
    let doubled: Vec<DVec3> = surface.iter().map(|&p| 2.0 * p).collect();
    let size = |points: &[DVec3]| points[0].distance(points[25]);
    let moved = follower.apply(&doubled).unwrap();
    assert!((size(&moved) - size(&eye)).abs() < 1e-9);
    let settings = FollowSettings {
        scale: true,
        ..FollowSettings::default()
    };
    let scaled = SurfaceFollower::new(&surface, &eye, &[0; 50], &[true], settings).unwrap();
    assert!((size(&scaled.apply(&doubled).unwrap()) - 2.0 * size(&eye)).abs() < 1e-9);
}

#[test]
fn each_number_of_neighbours_changes_the_binding_of_its_own_kind_of_part() {
    let surface = sphere(300, 1.0, DVec3::ZERO);
    // A rigid pair of points and a soft point, inside a surface bent unevenly.
    let parts = vec![
        DVec3::new(0.5, 0.0, 0.0),
        DVec3::new(0.5, 0.05, 0.0),
        DVec3::new(-0.5, 0.0, 0.0),
    ];
    let pieces = [0, 0, 1];
    let now: Vec<DVec3> = surface
        .iter()
        .map(|&p| p + DVec3::new(0.0, 0.3 * p.x * p.x * p.x, 0.1 * p.z * p.z))
        .collect();
    let moved = |settings: FollowSettings| {
        SurfaceFollower::new(&surface, &parts, &pieces, &[true, false], settings)
            .unwrap()
            .apply(&now)
            .unwrap()
    };
    let base = moved(FollowSettings::default());
    let rigid_few = moved(FollowSettings {
        neighbours: 4,
        ..FollowSettings::default()
    });
    let soft_few = moved(FollowSettings {
        soft_neighbours: 4,
        ..FollowSettings::default()
    });
    assert!(base[0].distance(rigid_few[0]) > 1e-4);
    assert!(base[2].distance(rigid_few[2]) < 1e-12);
    assert!(base[2].distance(soft_few[2]) > 1e-4);
    assert!(base[0].distance(soft_few[0]) < 1e-12);
}

#[test]
fn bad_inputs_are_refused_by_name() {
    let surface = sphere(20, 1.0, DVec3::ZERO);
    let part = vec![DVec3::ZERO; 3];
    let settings = FollowSettings::default();
    let refused = |result: Result<SurfaceFollower, KernelError>| result.unwrap_err();
    assert!(matches!(
        refused(SurfaceFollower::new(&[], &part, &[0; 3], &[true], settings)),
        KernelError::InvalidArgument {
            name: "surface",
            ..
        }
    ));
    assert!(matches!(
        refused(SurfaceFollower::new(
            &surface,
            &part,
            &[0; 2],
            &[true],
            settings
        )),
        KernelError::LengthMismatch { .. }
    ));
    assert!(matches!(
        refused(SurfaceFollower::new(
            &surface,
            &part,
            &[0, 1, 0],
            &[true],
            settings
        )),
        KernelError::InvalidArgument { name: "pieces", .. }
    ));
    let nan = vec![DVec3::ZERO, DVec3::NAN, DVec3::ZERO];
    assert!(matches!(
        refused(SurfaceFollower::new(
            &surface,
            &nan,
            &[0; 3],
            &[true],
            settings
        )),
        KernelError::NonFinite {
            what: "part vertex",
            index: 1
        }
    ));
    // Each number of neighbours out of its range, named (on a piece of its own kind).
    for (settings, rigid, name) in [
        (
            FollowSettings {
                neighbours: 0,
                ..settings
            },
            true,
            "neighbours",
        ),
        (
            FollowSettings {
                soft_neighbours: 2000,
                ..settings
            },
            false,
            "soft_neighbours",
        ),
        (
            FollowSettings {
                robust_rounds: 17,
                ..settings
            },
            true,
            "robust_rounds",
        ),
    ] {
        let error = refused(SurfaceFollower::new(
            &surface,
            &part,
            &[0; 3],
            &[rigid],
            settings,
        ));
        assert!(
            matches!(error, KernelError::InvalidArgument { name: named, .. } if named == name),
            "{error:?}"
        );
    }
    let follower = SurfaceFollower::new(&surface, &part, &[0; 3], &[true], settings).unwrap();
    assert!(matches!(
        follower.apply(&surface[..5]),
        Err(KernelError::LengthMismatch { .. })
    ));
    let mut far = surface.clone();
    far[2] = DVec3::new(1e9, 0.0, 0.0);
    assert!(matches!(
        follower.apply(&far),
        Err(KernelError::CoordinateOutOfRange { .. })
    ));
}

/// `point` reflected in the plane x = 0.
fn mirrored(point: DVec3) -> DVec3 {
    DVec3::new(-point.x, point.y, point.z)
}

#[test]
fn a_part_across_the_mirror_plane_moves_as_symmetrically_as_the_surface() {
    // A surface symmetric about x = 0 (each point with its mirror image, no point on the plane), a
    // part whose vertices lie on the plane (equally far from each surface point and its image),
    // and a symmetric, uneven motion of the surface.
    let half: Vec<DVec3> = sphere(600, 1.0, DVec3::ZERO)
        .into_iter()
        .filter(|point| point.x > 1e-3)
        .collect();
    let surface: Vec<DVec3> = half
        .iter()
        .flat_map(|&point| [point, mirrored(point)])
        .collect();
    let part: Vec<DVec3> = (0..12)
        .map(|i| {
            let angle = f64::from(i) * 0.5;
            DVec3::new(0.0, 0.2 * angle.cos() + 0.3, 0.2 * angle.sin())
        })
        .collect();
    let now: Vec<DVec3> = surface
        .iter()
        .map(|&p| {
            p + DVec3::new(
                0.2 * p.x * p.y,
                0.3 * p.x * p.x + 0.1 * p.z,
                0.2 * p.y * p.y,
            )
        })
        .collect();
    for rigid in [true, false] {
        for neighbours in [7, 31, 64] {
            let settings = FollowSettings {
                neighbours,
                soft_neighbours: neighbours,
                ..FollowSettings::default()
            };
            let moved = SurfaceFollower::new(&surface, &part, &[0; 12], &[rigid], settings)
                .unwrap()
                .apply(&now)
                .unwrap();
            for point in moved {
                assert!(point.x.abs() < 1e-12, "{point} ({rigid}, {neighbours})");
            }
        }
    }
}

#[test]
fn a_rigid_part_follows_its_surroundings_not_a_local_fold_over_it() {
    // An eyeball just under a sphere's surface; the surface turns and shifts as a whole, and a small
    // patch over the eyeball (a lid) also slides down across it, as a closing eyelid does.
    let surface = sphere(2000, 1.0, DVec3::ZERO);
    let eye = sphere(120, 0.12, DVec3::new(0.82, 0.0, 0.0));
    let lid = DVec3::new(1.0, 0.05, 0.0);
    let whole = |p: DVec3| {
        DVec3::new(0.3, -0.2, 0.5) + DQuat::from_rotation_y(0.4) * DQuat::from_rotation_x(-0.2) * p
    };
    let now: Vec<DVec3> = surface
        .iter()
        .map(|&p| {
            let reach = (1.0 - (p.distance(lid) / 0.22).powi(2)).max(0.0);
            whole(p + DVec3::new(0.0, -0.12 * reach * reach, 0.0))
        })
        .collect();
    // How far the eyeball ends from where the whole surface's motion takes it, at most.
    let error = |robust_rounds: usize| {
        let settings = FollowSettings {
            robust_rounds,
            ..FollowSettings::default()
        };
        SurfaceFollower::new(&surface, &eye, &[0; 120], &[true], settings)
            .unwrap()
            .apply(&now)
            .unwrap()
            .iter()
            .zip(&eye)
            .map(|(p, &r)| p.distance(whole(r)))
            .fold(0.0_f64, f64::max)
    };
    let plain = error(0);
    let robust = error(8);
    assert!(plain > 0.01, "the fold drags a plain fit: {plain}");
    assert!(
        robust < 0.1 * plain,
        "robust {robust} against plain {plain}"
    );
}
