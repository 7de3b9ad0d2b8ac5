//! Hostile value generators and the fuzz configuration shared by the targets.
#![allow(dead_code)]

use std::sync::{Arc, OnceLock};

use glam::Vec3;
use proptest::prelude::*;
use proptest::sample::select;
use proptest::test_runner::{Config, FileFailurePersistence};
use springwrap_kernel::{MAX_COORDINATE, TargetMesh, TargetMeshOptions};

use crate::common;

/// The configuration of a target: its base number of cases scaled by `SPRINGWRAP_FUZZ_SCALE`
/// (or `PROPTEST_CASES` cases when set), its failures saved in `regressions` (relative to the
/// kernel crate, where `cargo test` runs).
pub fn config(regressions: &'static str, base_cases: u32) -> Config {
    let cases = match std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|cases| cases.parse::<u32>().ok())
    {
        Some(cases) => cases,
        None => {
            let scale = std::env::var("SPRINGWRAP_FUZZ_SCALE")
                .ok()
                .and_then(|scale| scale.parse::<f64>().ok())
                .unwrap_or(1.0);
            ((f64::from(base_cases) * scale).round() as u32).max(1)
        }
    };
    Config {
        cases,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct(regressions))),
        max_shrink_iters: 4096,
        ..Config::default()
    }
}

/// Values no input should carry, and the edges of the kernel's bound.
pub const SPECIAL_VALUES: [f32; 16] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    -3.4e38,
    1e30,
    -1e30,
    MAX_COORDINATE,
    -MAX_COORDINATE,
    1.000_001e8,
    1e7,
    f32::MIN_POSITIVE,
    1e-30,
    -0.0,
    f32::EPSILON,
    f32::MIN_POSITIVE * 0.5, // a subnormal
];

/// A coordinate: mostly plausible (small, or a whole number so that vertices coincide and
/// triangles degenerate), sometimes special, sometimes any bit pattern.
pub fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        24 => -4.0f32..4.0,
        10 => (-2i32..=2).prop_map(|value| value as f32),
        4 => select(SPECIAL_VALUES.to_vec()),
        1 => any::<f32>(),
    ]
}

/// A mostly plausible coordinate (for the parts a target needs to get past its checks).
pub fn mild_coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        60 => -2.0f32..2.0,
        1 => select(SPECIAL_VALUES.to_vec()),
    ]
}

pub fn vector() -> impl Strategy<Value = Vec3> {
    (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

pub fn mild_vector() -> impl Strategy<Value = Vec3> {
    (mild_coordinate(), mild_coordinate(), mild_coordinate())
        .prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Barycentric weights: mostly a point of the triangle, sometimes anything.
pub fn barycentric() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        6 => (0.0f32..1.0, 0.0f32..1.0).prop_map(|(u, v)| {
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            Vec3::new(1.0 - u - v, u, v)
        }),
        1 => select(vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::splat(0.5), Vec3::new(-1.0, 2.0, 0.0)]),
        1 => vector(),
    ]
}

/// A search or step distance: plausible, zero, infinite (no limit), or broken.
pub fn distance() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => 0.0f32..5.0,
        1 => Just(0.0f32),
        2 => Just(f32::INFINITY),
        2 => select(SPECIAL_VALUES.to_vec()),
        1 => Just(-1.0f32),
        1 => any::<f32>(),
    ]
}

/// An index into `count` things: mostly valid, sometimes just past the end, sometimes absurd.
pub fn index(count: usize) -> impl Strategy<Value = u32> {
    let count = count as u32;
    prop_oneof![
        12 => 0..=count,
        1 => select(vec![u32::MAX, i32::MAX as u32, (i32::MAX as u32) + 1]),
        1 => any::<u32>(),
    ]
}

/// Vertices and triangles of a small mesh: duplicate vertices, degenerate triangles,
/// out-of-range indices and empty arrays all come up.
pub fn raw_mesh() -> impl Strategy<Value = (Vec<Vec3>, Vec<[u32; 3]>)> {
    prop::collection::vec(vector(), 0..10).prop_flat_map(|vertices| {
        let count = vertices.len();
        let triangle = [index(count), index(count), index(count)];
        (Just(vertices), prop::collection::vec(triangle, 0..14))
    })
}

/// A random small mesh its checks accept (duplicate vertices, degenerate and non-manifold
/// triangles, coordinates near the bound), or one of [`targets`] when they refuse it.
pub fn random_target() -> impl Strategy<Value = Arc<TargetMesh>> {
    let coordinate = prop_oneof![
        6 => -2.0f32..2.0,
        4 => (-1i32..=1).prop_map(|value| value as f32),
        1 => select(vec![MAX_COORDINATE, -MAX_COORDINATE, 1e7, 1e-20]),
    ];
    let vertex = (coordinate.clone(), coordinate.clone(), coordinate)
        .prop_map(|(x, y, z)| Vec3::new(x, y, z));
    (prop::collection::vec(vertex, 3..10), any::<usize>()).prop_flat_map(|(vertices, fallback)| {
        let count = vertices.len() as u32;
        (
            Just(vertices),
            prop::collection::vec([0..count, 0..count, 0..count], 1..14),
            Just(fallback),
        )
            .prop_map(|(vertices, triangles, fallback)| {
                TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).map_or_else(
                    |_| Arc::clone(&targets()[fallback % targets().len()]),
                    Arc::new,
                )
            })
    })
}

/// A few valid targets: a closed sphere, an open plane, a plane with a hole, a lumpy egg with a
/// hole, a tiny one, and one with degenerate triangles and a far vertex (within the bound).
pub fn targets() -> &'static [Arc<TargetMesh>] {
    static TARGETS: OnceLock<Vec<Arc<TargetMesh>>> = OnceLock::new();
    TARGETS.get_or_init(|| {
        let mesh = |(vertices, triangles): (Vec<Vec3>, Vec<[u32; 3]>)| {
            Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap())
        };
        let mut degenerate = common::grid(2);
        degenerate.0.push(Vec3::new(0.5, 0.5, 0.0));
        degenerate.0.push(Vec3::new(0.5, 0.5, 0.0));
        degenerate.0.push(Vec3::new(1e6, 0.0, 0.0));
        degenerate.1.push([9, 10, 9]);
        degenerate.1.push([0, 1, 11]);
        vec![
            mesh(common::uv_sphere(1.0, 5, 8)),
            common::plane_target(4, 1.0, 0.0),
            common::plane_target(6, 0.5, 0.6),
            mesh(common::lumpy_egg_with_hole(1.0, 6, 10, 0.4)),
            mesh((
                vec![Vec3::ZERO, Vec3::X * 1e-3, Vec3::Y * 1e-3],
                vec![[0, 1, 2]],
            )),
            mesh(degenerate),
        ]
    })
}

/// One of [`targets`].
pub fn target() -> impl Strategy<Value = Arc<TargetMesh>> {
    (0..targets().len()).prop_map(|index| Arc::clone(&targets()[index]))
}

/// Whether every component is finite.
pub fn finite(vector: Vec3) -> bool {
    vector.is_finite()
}
