//! Queries against a [`crate::TargetMesh`]: single and batched (parallel with rayon).

pub mod closest_point;
pub mod nearest_vertex;
pub mod point_triangle;
pub mod ray_cast;
pub mod ray_triangle;
pub(crate) mod triangle_packet;

use glam::Vec3;
use rayon::prelude::*;

use crate::error::KernelError;

/// Checks that every query position is finite and within the kernel's bound
/// ([`crate::validate::check_coordinates`]).
pub(crate) fn check_finite(what: &'static str, points: &[Vec3]) -> Result<(), KernelError> {
    crate::validate::check_coordinates(what, points)
}

/// Whether a single, unchecked query can run: `point` within the kernel's bound and
/// `max_distance` zero or more (what the batched queries check and refuse).
pub(crate) fn is_query(point: Vec3, max_distance: f32) -> bool {
    crate::validate::check_coordinate("point", 0, point).is_ok() && max_distance >= 0.0
}

/// Checks a search radius: zero or more, or infinite; never NaN.
pub(crate) fn check_max_distance(max_distance: f32) -> Result<(), KernelError> {
    if max_distance >= 0.0 {
        Ok(())
    } else {
        Err(KernelError::InvalidArgument {
            name: "max_distance",
            reason: format!("must be zero or more (infinity for no limit), got {max_distance}"),
        })
    }
}

/// What a worker carries from one query to the next: its traversal stack and the previous
/// answer (a BVH slot), used as a warm start.
#[derive(Default)]
pub(crate) struct QueryState {
    pub(crate) stack: crate::bvh::NearestStack,
    pub(crate) previous_slot: Option<usize>,
}

/// Queries per rayon task: large enough to amortise scheduling, small enough to balance 2+ cores.
pub(crate) const QUERIES_PER_TASK: usize = 512;

/// Batches smaller than this are answered in input order (sorting them would not pay).
const SPATIAL_ORDER_MIN_BATCH: usize = 4096;

/// Spreads the bits of a 21-bit integer three apart (for 63-bit Morton codes).
fn spread_bits(value: u64) -> u64 {
    let mut x = value & 0x1F_FFFF;
    x = (x | (x << 32)) & 0x1F_0000_0000_FFFF;
    x = (x | (x << 16)) & 0x1F_0000_FF00_00FF;
    x = (x | (x << 8)) & 0x100F_00F0_0F00_F00F;
    x = (x | (x << 4)) & 0x10C3_0C30_C30C_30C3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// The order in which to answer a batch: along a Morton (Z-order) curve through the points'
/// bounding box, so that consecutive queries are close in space whatever the caller's order.
pub(crate) fn spatial_order(points: &[Vec3]) -> Vec<u32> {
    let (min, max) = points
        .par_iter()
        .fold(
            || (Vec3::INFINITY, Vec3::NEG_INFINITY),
            |(min, max), &point| (min.min(point), max.max(point)),
        )
        .reduce(
            || (Vec3::INFINITY, Vec3::NEG_INFINITY),
            |(min_a, max_a), (min_b, max_b)| (min_a.min(min_b), max_a.max(max_b)),
        );
    let scale = (max - min).max(Vec3::splat(f32::MIN_POSITIVE)).recip() * 2_097_151.0;
    let mut keyed: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(index, &point)| {
            let cell = ((point - min) * scale).as_u64vec3();
            let code =
                spread_bits(cell.x) | (spread_bits(cell.y) << 1) | (spread_bits(cell.z) << 2);
            (code, index as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, index)| index).collect()
}

/// Answers `query(state, index)` for every index of `points`, in parallel and in spatial order,
/// returning the answers in input order. `state` is per worker and sees queries in spatial
/// order, so it can carry a warm start from one query to the next.
pub(crate) fn map_in_spatial_order<T, S, Init, Query>(
    points: &[Vec3],
    init: Init,
    query: Query,
) -> Vec<T>
where
    T: Send + Sync + Copy + Default,
    Init: Fn() -> S + Send + Sync,
    Query: Fn(&mut S, usize) -> T + Send + Sync,
{
    if points.len() < SPATIAL_ORDER_MIN_BATCH {
        return (0..points.len())
            .into_par_iter()
            .with_min_len(QUERIES_PER_TASK)
            .map_init(init, query)
            .collect();
    }
    let order = spatial_order(points);
    let sorted: Vec<T> = order
        .par_iter()
        .with_min_len(QUERIES_PER_TASK)
        .map_init(&init, |state, &index| query(state, index as usize))
        .collect();
    let mut answers = vec![T::default(); points.len()];
    for (&index, answer) in order.iter().zip(sorted) {
        answers[index as usize] = answer;
    }
    answers
}
