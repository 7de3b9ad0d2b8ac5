//! Feature curves as constraints: the automatic scale, joining pieces that continue each other,
//! and curves that run to where their crease ends, on a machined L-shaped part whose six blend
//! centre-lines are known (the same part as `benchmarks/feature_shapes.py`).

mod common;

use common::Rng;
use glam::{Vec2, Vec3};
use springwrap_kernel::features::join::join_chains;
use springwrap_kernel::features::scale::{AUTOMATIC_SCALE_MAX_EDGES, AUTOMATIC_SCALE_MIN_EDGES};
use springwrap_kernel::{
    FeatureCurve, FeatureCurveKind, FeatureSettings, KernelError, TargetMesh, TargetMeshOptions,
    automatic_scale, detect_features, mean_edge_length,
};

/// The L part (metres): x arm 0.40, y arm 0.30, arms 0.10 thick, extruded 0.20 along z.
const ARM_X: f32 = 0.40;
const ARM_Y: f32 = 0.30;
const THICKNESS: f32 = 0.10;
const DEPTH: f32 = 0.20;
/// The blends' radius.
const RADIUS: f32 = 0.04;

/// The L profile's six corners, counter-clockwise, and whether each is convex.
fn corners() -> [(Vec2, bool); 6] {
    [
        (Vec2::new(0.0, 0.0), true),
        (Vec2::new(ARM_X, 0.0), true),
        (Vec2::new(ARM_X, THICKNESS), true),
        (Vec2::new(THICKNESS, THICKNESS), false),
        (Vec2::new(THICKNESS, ARM_Y), true),
        (Vec2::new(0.0, ARM_Y), true),
    ]
}

/// The fillet of corner `index`: (centre, start, end) of its arc.
fn fillet(index: usize) -> (Vec2, Vec2, Vec2) {
    let all = corners();
    let corner = all[index].0;
    let previous = all[(index + 5) % 6].0;
    let following = all[(index + 1) % 6].0;
    let into = (previous - corner).normalize();
    let out = (following - corner).normalize();
    (
        corner + (into + out) * RADIUS,
        corner + into * RADIUS,
        corner + out * RADIUS,
    )
}

/// The filleted profile, counter-clockwise, points about `spacing` apart.
fn profile(spacing: f32) -> Vec<Vec2> {
    let mut points = Vec::new();
    for index in 0..6 {
        let (centre, start, end) = fillet(index);
        let a0 = (start - centre).y.atan2((start - centre).x);
        let a1 = (end - centre).y.atan2((end - centre).x);
        let mut sweep = a1 - a0;
        while sweep > std::f32::consts::PI {
            sweep -= std::f32::consts::TAU;
        }
        while sweep < -std::f32::consts::PI {
            sweep += std::f32::consts::TAU;
        }
        let steps = ((sweep.abs() * RADIUS / spacing).ceil() as usize).max(2);
        for step in 0..steps {
            let angle = a0 + sweep * step as f32 / steps as f32;
            points.push(centre + Vec2::new(angle.cos(), angle.sin()) * RADIUS);
        }
        let (_, next_start, _) = fillet((index + 1) % 6);
        let steps = ((next_start.distance(end) / spacing).ceil() as usize).max(1);
        for step in 0..steps {
            points.push(end.lerp(next_start, step as f32 / steps as f32));
        }
    }
    points
}

/// The closed L part: side walls a grid of about `spacing`, flat caps with sharp edges (a star
/// of rings round a point of the arms' common square, which sees the whole profile); triangles
/// wind outwards. With `noise`, every coordinate moves by a uniform amount in ±`noise`.
fn l_part(spacing: f32, noise: f32) -> TargetMesh {
    let outline = profile(spacing);
    let count = outline.len() as u32;
    let rows = ((DEPTH / spacing).round() as u32).max(2);
    let mut vertices: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for row in 0..=rows {
        let z = DEPTH * row as f32 / rows as f32;
        vertices.extend(outline.iter().map(|p| p.extend(z)));
    }
    for row in 0..rows {
        for i in 0..count {
            let (a, b) = (row * count + i, row * count + (i + 1) % count);
            let (c, d) = (a + count, b + count);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let centre = Vec2::splat(THICKNESS / 2.0);
    let reach = outline
        .iter()
        .map(|p| p.distance(centre))
        .fold(0.0f32, f32::max);
    let ring_count = ((reach / spacing).ceil() as u32).max(2);
    for (top, z, outer_row) in [(false, 0.0, 0), (true, DEPTH, rows)] {
        let first = vertices.len() as u32;
        for k in 1..ring_count {
            let fraction = 1.0 - k as f32 / ring_count as f32;
            vertices.extend(
                outline
                    .iter()
                    .map(|&p| (centre + (p - centre) * fraction).extend(z)),
            );
        }
        let apex = vertices.len() as u32;
        vertices.push(centre.extend(z));
        let ring = |k: u32, i: u32| {
            if k == 0 {
                outer_row * count + i % count
            } else {
                first + (k - 1) * count + i % count
            }
        };
        let mut push = |corners: [u32; 3]| {
            triangles.push(if top {
                [corners[2], corners[1], corners[0]]
            } else {
                corners
            });
        };
        for k in 0..ring_count - 1 {
            for i in 0..count {
                let (a, b) = (ring(k, i), ring(k, i + 1));
                let (c, d) = (ring(k + 1, i), ring(k + 1, i + 1));
                push([a, c, d]);
                push([a, d, b]);
            }
        }
        for i in 0..count {
            push([ring(ring_count - 1, i), apex, ring(ring_count - 1, i + 1)]);
        }
    }
    if noise > 0.0 {
        let mut rng = Rng::new(5);
        for vertex in &mut vertices {
            *vertex += Vec3::new(
                rng.range(-noise, noise),
                rng.range(-noise, noise),
                rng.range(-noise, noise),
            );
        }
    }
    TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap()
}

/// The six blend centre-lines (z from 0 to the depth) and their kinds.
fn centre_lines() -> Vec<((Vec3, Vec3), FeatureCurveKind)> {
    (0..6)
        .map(|index| {
            let (centre, start, end) = fillet(index);
            let point = centre + ((start + end) * 0.5 - centre).normalize() * RADIUS;
            let kind = if corners()[index].1 {
                FeatureCurveKind::Ridge
            } else {
                FeatureCurveKind::Valley
            };
            ((point.extend(0.0), point.extend(DEPTH)), kind)
        })
        .collect()
}

fn distance_to_segment(point: Vec3, (start, end): (Vec3, Vec3)) -> f32 {
    let direction = end - start;
    let t = ((point - start).dot(direction) / direction.length_squared()).clamp(0.0, 1.0);
    point.distance(start + direction * t)
}

fn median(mut values: Vec<f32>) -> f32 {
    values.sort_by(f32::total_cmp);
    values[values.len() / 2]
}

/// How the curves do against one centre-line: the fraction of the line within `tolerance` of a
/// curve of its kind, the points of the curves that follow it (median point within `tolerance`),
/// and how far those stop short of the line's two ends, measured along it.
struct LineMeasure {
    coverage: f32,
    following: Vec<Vec3>,
    gaps: (f32, f32),
}

fn measure(
    curves: &[FeatureCurve],
    line: (Vec3, Vec3),
    kind: FeatureCurveKind,
    tolerance: f32,
) -> LineMeasure {
    // The curves densely resampled (every 2 mm), for the coverage.
    let mut dense: Vec<Vec3> = Vec::new();
    let mut following: Vec<Vec3> = Vec::new();
    for curve in curves.iter().filter(|curve| curve.kind == kind) {
        for pair in curve.points.windows(2) {
            let pieces = (pair[0].distance(pair[1]) / 0.002).ceil().max(1.0) as usize;
            for piece in 0..pieces {
                dense.push(pair[0].lerp(pair[1], piece as f32 / pieces as f32));
            }
        }
        dense.extend(curve.points.last());
        let distances = curve
            .points
            .iter()
            .map(|&p| distance_to_segment(p, line))
            .collect();
        if median(distances) <= tolerance {
            following.extend(&curve.points);
        }
    }
    let samples = 100;
    let covered = (0..=samples)
        .filter(|&sample| {
            let point = line.0.lerp(line.1, sample as f32 / samples as f32);
            dense.iter().any(|&p| p.distance(point) <= tolerance)
        })
        .count();
    let axis = line.1 - line.0;
    let length = axis.length();
    let along: Vec<f32> = following
        .iter()
        .map(|&p| (p - line.0).dot(axis) / length)
        .collect();
    let lowest = along.iter().copied().fold(f32::INFINITY, f32::min);
    let highest = along.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    LineMeasure {
        coverage: covered as f32 / (samples + 1) as f32,
        following,
        gaps: (lowest.max(0.0), (length - highest).max(0.0)),
    }
}

/// Detects with `settings` on the L part and checks every blend: covered at least `coverage`
/// within a quarter of the radius, followed with a mean offset below `offset`, reached to within
/// `gap` of both caps. Returns the scale used.
fn check_l_part(
    noise: f32,
    settings: &FeatureSettings,
    coverage: f32,
    offset: f32,
    gap: f32,
) -> f32 {
    let part = l_part(0.0065, noise);
    let features = detect_features(&part, settings).unwrap();
    let tolerance = 0.25 * RADIUS;
    let mut offsets = Vec::new();
    for (index, (line, kind)) in centre_lines().into_iter().enumerate() {
        let found = measure(&features.curves, line, kind, tolerance);
        let mean = found
            .following
            .iter()
            .map(|&p| distance_to_segment(p, line))
            .sum::<f32>()
            / found.following.len().max(1) as f32;
        println!(
            "blend {index} ({kind:?}): coverage {:.3}, mean offset {mean:.4}, gaps to the caps {:.4} / {:.4}",
            found.coverage, found.gaps.0, found.gaps.1
        );
        assert!(
            found.coverage >= coverage,
            "blend {index} covered {}",
            found.coverage
        );
        assert!(
            mean < offset,
            "blend {index} followed {mean} off on average"
        );
        assert!(
            found.gaps.0 <= gap && found.gaps.1 <= gap,
            "blend {index}: curves stop {:?} short of the caps",
            found.gaps
        );
        offsets.push(mean);
    }
    println!(
        "L part (noise {noise}): scale {:.4}, {} curves",
        features.scale,
        features.curves.len()
    );
    features.scale
}

#[test]
fn the_l_part_blends_are_found_at_the_automatic_scale() {
    // Noise of ±0.8 mm (a scan of the part). At the automatic scale (a tenth of the diagonal,
    // 0.054: about the blend radius) every blend is covered over at least 90 % of its length
    // within a quarter of its radius (what is missed: the last centimetres, where the cap's sharp
    // edge pulls the fit aside), followed 5 mm off at most on average, and reached to within
    // 5 mm of both caps.
    let scale = check_l_part(0.0008, &FeatureSettings::default(), 0.9, 0.005, 0.005);
    let diagonal = Vec3::new(ARM_X, ARM_Y, DEPTH).length();
    assert!((scale - 0.1 * diagonal).abs() < 1e-3, "scale {scale}");
}

#[test]
fn the_clean_l_part_curves_run_to_the_caps() {
    // Without noise: covered over 90 % of its length, 3 mm off on average, ending on the caps.
    check_l_part(0.0, &FeatureSettings::default(), 0.9, 0.003, 0.002);
}

#[test]
fn a_layout_edge_length_sets_the_automatic_scale() {
    // A layout with 5 cm edges: the scale is 0.05, and the blends are found as well.
    let scale = check_l_part(0.0, &FeatureSettings::for_layout(0.05), 0.9, 0.003, 0.002);
    assert!((scale - 0.05).abs() < 1e-6, "scale {scale}");
}

#[test]
fn the_automatic_scale_is_bounded_by_the_edges() {
    let part = l_part(0.0065, 0.0);
    let edge = mean_edge_length(&part);
    let diagonal = Vec3::new(ARM_X, ARM_Y, DEPTH).length();
    assert!((automatic_scale(&part, 0.0).unwrap() - 0.1 * diagonal).abs() < 1e-4);
    assert!((automatic_scale(&part, 0.05).unwrap() - 0.05).abs() < 1e-6);
    // A layout edge below 6 mesh edges or above 30: held at those.
    assert_eq!(
        (AUTOMATIC_SCALE_MIN_EDGES, AUTOMATIC_SCALE_MAX_EDGES),
        (6.0, 30.0)
    );
    assert!((automatic_scale(&part, 1e-4).unwrap() - 6.0 * edge).abs() < 1e-6);
    assert!((automatic_scale(&part, 10.0).unwrap() - 30.0 * edge).abs() < 1e-5);
    for bad in [-1.0, f32::NAN, f32::INFINITY] {
        assert!(
            matches!(
                automatic_scale(&part, bad),
                Err(KernelError::InvalidArgument {
                    name: "layout_edge_length",
                    ..
                })
            ),
            "{bad}"
        );
        let settings = FeatureSettings::for_layout(bad);
        assert!(detect_features(&part, &settings).is_err(), "{bad}");
    }
    let settings = FeatureSettings {
        hysteresis: 1.5,
        ..FeatureSettings::default()
    };
    assert!(matches!(
        detect_features(&part, &settings),
        Err(KernelError::InvalidArgument {
            name: "hysteresis",
            ..
        })
    ));
}

fn line(from: Vec3, to: Vec3, count: usize) -> Vec<Vec3> {
    (0..count)
        .map(|i| from.lerp(to, i as f32 / (count - 1) as f32))
        .collect()
}

#[test]
fn pieces_that_continue_each_other_are_joined() {
    // Two pieces of one straight line with a gap of 0.5, the second one reversed: joined into one
    // open chain running from 0 to 5 within a join distance of 1.
    let first = line(Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), 9);
    let second = line(Vec3::new(5.0, 0.0, 0.0), Vec3::new(2.5, 0.0, 0.0), 9);
    let joined = join_chains(vec![(first.clone(), false), (second.clone(), false)], 1.0);
    assert_eq!(joined.len(), 1);
    let (points, closed) = &joined[0];
    assert!(!closed);
    assert_eq!(points.len(), 18);
    let ends = [points[0].x, points[17].x];
    assert!(ends == [0.0, 5.0] || ends == [5.0, 0.0], "{ends:?}");
    // The same gap beyond the join distance: two chains.
    assert_eq!(
        join_chains(vec![(first.clone(), false), (second, false)], 0.4).len(),
        2
    );
    // A piece meeting the first at a right angle (a box's corner): not joined.
    let across = line(Vec3::new(2.3, 0.2, 0.0), Vec3::new(2.3, 3.0, 0.0), 9);
    assert_eq!(
        join_chains(vec![(first.clone(), false), (across, false)], 1.0).len(),
        2
    );
    // A piece running alongside, not on: not joined either.
    let beside = line(Vec3::new(2.5, 0.9, 0.0), Vec3::new(5.0, 0.9, 0.0), 9);
    assert_eq!(
        join_chains(vec![(first, false), (beside, false)], 1.0).len(),
        2
    );
}

#[test]
fn a_chain_whose_ends_meet_is_closed() {
    // A racetrack (straights 20 long, half circles of radius 1) traced from the middle of one
    // straight round to 0.4 short of where it started: its ends meet in line, it is closed.
    let mut points = line(Vec3::ZERO, Vec3::new(10.0, 0.0, 0.0), 21);
    for step in 1..20 {
        let angle = std::f32::consts::PI * step as f32 / 20.0;
        points.push(Vec3::new(10.0 + angle.sin(), 1.0 - angle.cos(), 0.0));
    }
    points.extend(line(
        Vec3::new(10.0, 2.0, 0.0),
        Vec3::new(-10.0, 2.0, 0.0),
        41,
    ));
    for step in 1..20 {
        let angle = std::f32::consts::PI * step as f32 / 20.0;
        points.push(Vec3::new(-10.0 - angle.sin(), 1.0 + angle.cos(), 0.0));
    }
    points.extend(line(
        Vec3::new(-10.0, 0.0, 0.0),
        Vec3::new(-0.4, 0.0, 0.0),
        20,
    ));
    let joined = join_chains(vec![(points, false)], 0.5);
    assert_eq!(joined.len(), 1);
    assert!(joined[0].1, "the racetrack should be closed");
    // Its ends further apart than the join distance: left open.
    let (points, _) = joined[0].clone();
    let open = points[..points.len() - 3].to_vec();
    assert!(!join_chains(vec![(open, false)], 0.5)[0].1);
}
