//! Correspondence proposals on a bumpy ball whose proportions change: the tips and pits not
//! anchored are found where the change puts them, the settings bound the answer, and bad input is
//! refused with the error that names it.

mod common;

use common::uv_sphere;
use glam::Vec3;
use springwrap_kernel::{
    GivenPair, KernelError, LayoutFaces, ProposalLayout, ProposalSettings, TargetMesh,
    TargetMeshOptions, propose_correspondences,
};

/// Directions of the ball's tips (raised) and pits (sunk), away from the poles.
fn features() -> Vec<(Vec3, f32)> {
    let mut out = Vec::new();
    for k in 0..8 {
        let azimuth = std::f32::consts::TAU * k as f32 / 8.0;
        let polar: f32 = if k % 2 == 0 { 1.1 } else { 2.0 };
        let direction = Vec3::new(
            polar.sin() * azimuth.cos(),
            polar.sin() * azimuth.sin(),
            polar.cos(),
        );
        out.push((direction, if k % 4 == 3 { -0.12 } else { 0.35 }));
    }
    out
}

/// A ball of radius 1 with narrow bumps (tips) and dimples (pits) along [`features`].
fn bumpy_ball(rings: u32, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut vertices, triangles) = uv_sphere(1.0, rings, segments);
    let bumps = features();
    for v in &mut vertices {
        let u = v.normalize();
        let radius: f32 = 1.0
            + bumps
                .iter()
                .map(|&(d, height)| height * (-(1.0 - u.dot(d)) / 0.012).exp())
                .sum::<f32>();
        *v = u * radius;
    }
    (vertices, triangles)
}

/// The change of proportions from the layout's rest shape to the target.
fn stretch(p: Vec3) -> Vec3 {
    Vec3::new(1.15 * p.x, p.y, 0.9 * p.z) + Vec3::new(0.1, -0.2, 0.05)
}

struct Case {
    target: TargetMesh,
    rest: Vec<Vec3>,
    current: Vec<Vec3>,
    corners: Vec<u32>,
    sizes: Vec<u32>,
    truth: Vec<Vec3>,
}

/// The layout: a coarser ball at rest; its current fit the uniform scale that Align would give;
/// the target: a finer ball, stretched. The truth: each layout vertex stretched.
fn case() -> Case {
    let (rest, triangles) = bumpy_ball(60, 90);
    let (fine, fine_triangles) = bumpy_ball(110, 170);
    let target = TargetMesh::new(
        fine.iter().map(|&p| stretch(p)).collect(),
        fine_triangles,
        TargetMeshOptions::default(),
    )
    .unwrap();
    let current = rest
        .iter()
        .map(|&p| p * 1.05 + Vec3::new(0.1, -0.2, 0.05))
        .collect();
    let truth = rest.iter().map(|&p| stretch(p)).collect();
    Case {
        target,
        corners: triangles.iter().flatten().copied().collect(),
        sizes: vec![3; triangles.len()],
        rest,
        current,
        truth,
    }
}

impl Case {
    fn layout(&self) -> ProposalLayout<'_> {
        ProposalLayout {
            rest: &self.rest,
            current: &self.current,
            faces: LayoutFaces {
                corners: &self.corners,
                sizes: &self.sizes,
            },
        }
    }

    /// The layout vertex nearest each feature's tip at rest.
    fn feature_vertices(&self) -> Vec<u32> {
        features()
            .iter()
            .map(|&(d, height)| {
                let tip = d * (1.0 + height);
                (0..self.rest.len() as u32)
                    .min_by(|&a, &b| {
                        self.rest[a as usize]
                            .distance(tip)
                            .total_cmp(&self.rest[b as usize].distance(tip))
                    })
                    .unwrap()
            })
            .collect()
    }

    /// Anchors on the first `count` features, at their true points.
    fn given(&self, count: usize) -> Vec<GivenPair> {
        self.feature_vertices()
            .into_iter()
            .take(count)
            .map(|vertex| GivenPair {
                vertex,
                target: self.truth[vertex as usize],
            })
            .collect()
    }
}

/// The settings with a least confidence below the default's: the ball, with 3 anchors only, has few
/// pairs above the default.
fn loose() -> ProposalSettings {
    ProposalSettings {
        min_confidence: 0.3,
        ..ProposalSettings::default()
    }
}

#[test]
fn unanchored_tips_and_pits_are_proposed_near_their_true_points() {
    let case = case();
    let given = case.given(3);
    let proposals = propose_correspondences(&case.target, case.layout(), &given, &loose()).unwrap();
    let (low, high) = case.target.bounding_box();
    let diagonal = (high - low).length();
    assert!(
        proposals.len() >= 3,
        "{} proposals: {proposals:?}",
        proposals.len()
    );
    for proposal in &proposals {
        assert!((0.0..=1.0).contains(&proposal.confidence));
        assert!(given.iter().all(|g| g.vertex != proposal.vertex));
        let error = proposal
            .position
            .distance(case.truth[proposal.vertex as usize]);
        assert!(
            error < 0.02 * diagonal,
            "vertex {} off by {error}",
            proposal.vertex
        );
        let on_surface = case
            .target
            .face_point_position(proposal.face_point)
            .unwrap();
        assert!(on_surface.distance(proposal.position) < 1e-5);
    }
    // Most confident first.
    assert!(
        proposals
            .windows(2)
            .all(|w| w[0].confidence >= w[1].confidence)
    );
}

#[test]
fn every_setting_changes_the_answer() {
    let case = case();
    let given = case.given(3);
    let defaults = loose();
    let all = propose_correspondences(&case.target, case.layout(), &given, &defaults).unwrap();
    assert!(all.len() >= 3);
    // The default least confidence keeps the surest of them.
    let default = ProposalSettings::default();
    assert!(default.min_confidence > defaults.min_confidence);
    let surest = propose_correspondences(&case.target, case.layout(), &given, &default).unwrap();
    let expected: Vec<_> = all
        .iter()
        .copied()
        .filter(|p| p.confidence >= default.min_confidence)
        .collect();
    assert_eq!(surest, expected);
    let two = ProposalSettings {
        max_count: 2,
        ..defaults
    };
    let few = propose_correspondences(&case.target, case.layout(), &given, &two).unwrap();
    assert_eq!(few, all[..2]);
    let strict = ProposalSettings {
        min_confidence: all[1].confidence + 1e-6,
        ..defaults
    };
    let sure = propose_correspondences(&case.target, case.layout(), &given, &strict).unwrap();
    assert!(sure.len() < all.len() && !sure.is_empty());
    // A search radius below the fit's error finds nothing there.
    let narrow = ProposalSettings {
        search_radius: 0.002,
        ..defaults
    };
    let none = propose_correspondences(&case.target, case.layout(), &given, &narrow).unwrap();
    assert!(none.len() < all.len());
    // A feature scale far above the bumps sees none of them as distinct.
    let coarse = ProposalSettings {
        feature_scale: 0.08,
        ..defaults
    };
    let other = propose_correspondences(&case.target, case.layout(), &given, &coarse).unwrap();
    assert_ne!(other, all);
}

#[test]
fn bad_input_is_refused_by_name() {
    let case = case();
    let given = case.given(3);
    let settings = ProposalSettings::default();
    let run = |layout: ProposalLayout<'_>, given: &[GivenPair], settings: &ProposalSettings| {
        propose_correspondences(&case.target, layout, given, settings).unwrap_err()
    };
    assert!(matches!(
        run(case.layout(), &given[..2], &settings),
        KernelError::TooFewPairs {
            given: 2,
            needed: 3,
            ..
        }
    ));
    let repeated = [given[0], given[0], given[1]];
    assert!(matches!(
        run(case.layout(), &repeated, &settings),
        KernelError::TooFewPairs { given: 2, .. }
    ));
    let mut missing = given.clone();
    missing[1].vertex = case.rest.len() as u32;
    assert!(matches!(
        run(case.layout(), &missing, &settings),
        KernelError::LayoutIndexOutOfRange {
            element: "anchor",
            index: 1,
            ..
        }
    ));
    let mut nan = given.clone();
    nan[2].target = Vec3::NAN;
    assert!(matches!(
        run(case.layout(), &nan, &settings),
        KernelError::NonFinite {
            what: "anchor target",
            index: 2
        }
    ));
    let short = ProposalLayout {
        current: &case.current[1..],
        ..case.layout()
    };
    assert!(matches!(
        run(short, &given, &settings),
        KernelError::LengthMismatch { .. }
    ));
    let mut bad_rest = case.rest.clone();
    bad_rest[5] = Vec3::new(f32::INFINITY, 0.0, 0.0);
    let layout = ProposalLayout {
        rest: &bad_rest,
        ..case.layout()
    };
    assert!(matches!(
        run(layout, &given, &settings),
        KernelError::NonFinite { index: 5, .. }
    ));
    let mut corners = case.corners.clone();
    corners[7] = 1_000_000;
    let layout = ProposalLayout {
        faces: LayoutFaces {
            corners: &corners,
            sizes: &case.sizes,
        },
        ..case.layout()
    };
    assert!(matches!(
        run(layout, &given, &settings),
        KernelError::LayoutIndexOutOfRange {
            element: "face",
            ..
        }
    ));
    let faceless = ProposalLayout {
        faces: LayoutFaces {
            corners: &[],
            sizes: &[],
        },
        ..case.layout()
    };
    assert!(matches!(
        run(faceless, &given, &settings),
        KernelError::InvalidArgument { name: "faces", .. }
    ));
    for (bad, name) in [
        (
            ProposalSettings {
                max_count: 0,
                ..settings
            },
            "max_count",
        ),
        (
            ProposalSettings {
                min_confidence: 1.5,
                ..settings
            },
            "min_confidence",
        ),
        (
            ProposalSettings {
                search_radius: f32::NAN,
                ..settings
            },
            "search_radius",
        ),
        (
            ProposalSettings {
                feature_scale: 0.0,
                ..settings
            },
            "feature_scale",
        ),
    ] {
        match run(case.layout(), &given, &bad) {
            KernelError::InvalidArgument { name: found, .. } => assert_eq!(found, name),
            other => panic!("{other:?}"),
        }
    }
    // Three anchors on one vertex's spot on both sides.
    let same_place: Vec<GivenPair> = (0..3)
        .map(|k| GivenPair {
            vertex: k,
            target: Vec3::new(0.1, -0.2, 0.05 + 0.9),
        })
        .collect();
    let mut rest = case.rest.clone();
    rest[1] = rest[0];
    rest[2] = rest[0];
    let layout = ProposalLayout {
        rest: &rest,
        ..case.layout()
    };
    assert!(matches!(
        run(layout, &same_place, &settings),
        KernelError::CoincidentAnchors { .. }
    ));
}

/// A unit direction at `azimuth` degrees about +Z from +X and `polar` radians from +Z.
fn direction(azimuth: f32, polar: f32) -> Vec3 {
    let azimuth = azimuth.to_radians();
    Vec3::new(
        polar.sin() * azimuth.cos(),
        polar.sin() * azimuth.sin(),
        polar.cos(),
    )
}

/// A ball with a narrow tip along each of `tips`, made an ellipsoid.
fn tipped_ellipsoid(rings: u32, segments: u32, tips: &[Vec3]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut vertices, triangles) = uv_sphere(1.0, rings, segments);
    for v in &mut vertices {
        let u = v.normalize();
        let radius: f32 = 1.0
            + tips
                .iter()
                .map(|&d| 0.35 * (-(1.0 - u.dot(d)) / 0.012).exp())
                .sum::<f32>();
        *v = u * radius * Vec3::new(1.0, 1.3, 0.8);
    }
    (vertices, triangles)
}

#[test]
fn a_match_found_on_one_side_of_a_mirrored_layout_only_is_rejected() {
    // The layout: mirror-symmetric across x = 0 (azimuth a ↔ 180° − a), four tips on the plane
    // (anchored) and three pairs of tips across it.
    let midline = [(90.0, 0.6), (270.0, 1.4), (90.0, 2.6), (270.0, 2.4)];
    let pairs = [(30.0, 1.2), (60.0, 2.1), (320.0, 1.0)];
    let mut tips: Vec<Vec3> = midline.iter().map(|&(a, p)| direction(a, p)).collect();
    for &(a, p) in &pairs {
        tips.push(direction(a, p));
        tips.push(direction(180.0 - a, p));
    }
    let (rest, triangles) = tipped_ellipsoid(60, 90, &tips);
    // The target: the same shape, except that the first pair's left tip (150°) is gone and its
    // right one (30°) stands 6° away: the right tip's only candidate is wrong, and it has no
    // partner on the left.
    let moved = direction(36.0, 1.2);
    let target_tips: Vec<Vec3> = tips
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != 5)
        .map(|(k, &d)| if k == 4 { moved } else { d })
        .collect();
    let place = |p: Vec3| p * 1.05 + Vec3::new(0.1, -0.2, 0.05);
    let (fine, fine_triangles) = tipped_ellipsoid(110, 170, &target_tips);
    let target = TargetMesh::new(
        fine.into_iter().map(place).collect(),
        fine_triangles,
        TargetMeshOptions::default(),
    )
    .unwrap();
    let current: Vec<Vec3> = rest.iter().map(|&p| place(p)).collect();
    let nearest = |point: Vec3| {
        (0..rest.len() as u32)
            .min_by(|&a, &b| {
                rest[a as usize]
                    .distance(point)
                    .total_cmp(&rest[b as usize].distance(point))
            })
            .unwrap()
    };
    let tip_vertex = |d: Vec3| nearest(d * 1.35 * Vec3::new(1.0, 1.3, 0.8));
    let given: Vec<GivenPair> = tips[..4]
        .iter()
        .map(|&d| {
            let vertex = tip_vertex(d);
            GivenPair {
                vertex,
                target: current[vertex as usize],
            }
        })
        .collect();
    let corners: Vec<u32> = triangles.iter().flatten().copied().collect();
    let sizes = vec![3; triangles.len()];
    let layout = ProposalLayout {
        rest: &rest,
        current: &current,
        faces: LayoutFaces {
            corners: &corners,
            sizes: &sizes,
        },
    };
    let proposals = propose_correspondences(&target, layout, &given, &loose()).unwrap();
    let (low, high) = target.bounding_box();
    let diagonal = (high - low).length();
    let near = |proposal: &springwrap_kernel::Proposal, d: Vec3| {
        rest[proposal.vertex as usize].distance(rest[tip_vertex(d) as usize]) < 0.05 * diagonal
    };
    // The one-sided wrong match is not proposed.
    assert!(proposals.iter().all(|p| !near(p, tips[4])), "{proposals:?}");
    // The last pair, found on both sides, is.
    for d in &tips[8..] {
        assert!(proposals.iter().any(|p| near(p, *d)), "{d} {proposals:?}");
    }
}
