//! The layout's mirror symmetry: most layouts of bodies and faces are modelled with a mirror, so
//! each vertex has a partner across a plane. A proposal on a feature with a partner (an elbow, a
//! buttock) is trusted only when the partner's feature is proposed too, at a consistent distance:
//! both shapes being near-symmetric, a right match on one side has a right match on the other,
//! and a match found on one side only is more often a wrong one (measured on the benchmark bodies,
//! `benchmarks/few_anchors.py`; see [`super::propose_correspondences`]).

use std::collections::HashMap;

use glam::Vec3;

use super::Proposal;
use super::matching::MAX_INCONSISTENCY;
use crate::align::linear_algebra::symmetric_eigen;

/// How close a vertex's mirror image must come to another vertex for them to be partners, as a
/// fraction of the shape's bounding-box diagonal.
const MIRROR_TOLERANCE: f32 = 0.0005;
/// The least share of vertices with a partner for the shape to count as mirror-symmetric.
const MIN_SYMMETRIC_SHARE: f32 = 0.99;

/// Each vertex's mirror partner (itself on the plane), when the shape is mirror-symmetric about a
/// plane through its centroid normal to one of its principal axes or coordinate axes; `None`
/// otherwise. Vertices
/// without a partner within the tolerance map to `u32::MAX`.
pub(crate) fn mirror_partners(positions: &[Vec3], diagonal: f32) -> Option<Vec<u32>> {
    if positions.len() < 2 || diagonal <= 0.0 || !diagonal.is_finite() {
        return None;
    }
    let count = positions.len() as f64;
    let centroid = positions
        .iter()
        .fold([0.0f64; 3], |sum, p| {
            [
                sum[0] + f64::from(p.x),
                sum[1] + f64::from(p.y),
                sum[2] + f64::from(p.z),
            ]
        })
        .map(|s| s / count);
    let mut covariance = [[0.0f64; 3]; 3];
    for p in positions {
        let d = [
            f64::from(p.x) - centroid[0],
            f64::from(p.y) - centroid[1],
            f64::from(p.z) - centroid[2],
        ];
        for (row, &a) in covariance.iter_mut().zip(&d) {
            for (entry, &b) in row.iter_mut().zip(&d) {
                *entry += a * b;
            }
        }
    }
    let (_, axes) = symmetric_eigen(covariance);
    let centre = Vec3::new(centroid[0] as f32, centroid[1] as f32, centroid[2] as f32);
    let tolerance = MIRROR_TOLERANCE * diagonal;
    let grid = Grid::new(positions, tolerance);
    let needed = (MIN_SYMMETRIC_SHARE * positions.len() as f32).ceil() as usize;
    // The principal axes, and the coordinate axes (a layout modelled with a mirror modifier: its
    // principal axes are unreliable when two spreads are alike).
    axes.iter()
        .map(|axis| Vec3::new(axis[0] as f32, axis[1] as f32, axis[2] as f32).normalize())
        .chain([Vec3::X, Vec3::Y, Vec3::Z])
        .map(|normal| {
            let partners: Vec<u32> = positions
                .iter()
                .map(|&p| {
                    let image = p - 2.0 * (p - centre).dot(normal) * normal;
                    grid.nearest_within(positions, image, tolerance)
                        .unwrap_or(u32::MAX)
                })
                .collect();
            let found = partners.iter().filter(|&&v| v != u32::MAX).count();
            (found, partners)
        })
        .filter(|(found, _)| *found >= needed)
        .max_by_key(|(found, _)| *found)
        .map(|(_, partners)| partners)
}

/// The proposals without those on one side only: a proposal whose vertex has a mirror partner
/// (on a mirror-symmetric layout, farther than `radius` from it at rest and farther than
/// `clearance` from every anchor) is kept only when a proposal lies within `radius` of that partner
/// at rest, at a distance from it on the target that is its distance at rest times `scale` within
/// [`MAX_INCONSISTENCY`].
pub(crate) fn bilateral(
    proposals: Vec<Proposal>,
    rest: &[Vec3],
    diagonal: f32,
    radius: f32,
    anchor_rest: &[Vec3],
    clearance: f32,
    scale: f32,
) -> Vec<Proposal> {
    let Some(partners) = mirror_partners(rest, diagonal) else {
        return proposals;
    };
    let keep: Vec<bool> = proposals
        .iter()
        .map(|p| {
            let here = rest[p.vertex as usize];
            let partner = partners[p.vertex as usize];
            if partner == u32::MAX {
                return true;
            }
            let mirror = rest[partner as usize];
            if mirror.distance(here) <= radius
                || anchor_rest.iter().any(|a| a.distance(mirror) <= clearance)
            {
                return true;
            }
            proposals.iter().any(|q| {
                let there = rest[q.vertex as usize];
                q.vertex != p.vertex && there.distance(mirror) <= radius && {
                    let ratio = q.position.distance(p.position) / (scale * there.distance(here));
                    ratio.max(1e-6).ln().abs() <= MAX_INCONSISTENCY
                }
            })
        })
        .collect();
    proposals
        .into_iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(p))
        .collect()
}

/// Points hashed into cubes of one tolerance.
struct Grid {
    cell: f32,
    cells: HashMap<[i32; 3], Vec<u32>>,
}

impl Grid {
    fn new(positions: &[Vec3], cell: f32) -> Self {
        let mut cells: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
        for (index, &p) in positions.iter().enumerate() {
            cells
                .entry(Self::key(p, cell))
                .or_default()
                .push(index as u32);
        }
        Self { cell, cells }
    }

    fn key(p: Vec3, cell: f32) -> [i32; 3] {
        (p / cell).floor().as_ivec3().to_array()
    }

    /// The nearest point within `radius` (at most one cell) of `query`; ties to the lower index.
    fn nearest_within(&self, positions: &[Vec3], query: Vec3, radius: f32) -> Option<u32> {
        let [x, y, z] = Self::key(query, self.cell);
        let mut best: Option<(f32, u32)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(members) = self.cells.get(&[x + dx, y + dy, z + dz]) else {
                        continue;
                    };
                    for &v in members {
                        let distance = positions[v as usize].distance(query);
                        if distance <= radius
                            && best.is_none_or(|(d, b)| distance < d || (distance == d && v < b))
                        {
                            best = Some((distance, v));
                        }
                    }
                }
            }
        }
        best.map(|(_, v)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mirrored_cloud_pairs_its_points_and_a_lopsided_one_does_not() {
        // Points on both sides of the plane x = 0.3, turned so that the plane is no coordinate plane.
        let half = [
            Vec3::new(1.0, 0.2, 0.1),
            Vec3::new(2.0, 1.5, -0.4),
            Vec3::new(0.7, -1.0, 0.9),
            Vec3::new(1.4, 0.4, -1.2),
        ];
        let turn = glam::Quat::from_rotation_y(0.4);
        let mut points: Vec<Vec3> = half.iter().map(|&p| p + Vec3::X * 0.3).collect();
        points.extend(
            half.iter()
                .map(|&p| Vec3::new(-p.x, p.y, p.z) + Vec3::X * 0.3),
        );
        points.push(Vec3::new(0.3, 3.0, 0.0));
        let points: Vec<Vec3> = points.iter().map(|&p| turn * p).collect();
        let partners = mirror_partners(&points, 5.0).expect("symmetric");
        for k in 0..4 {
            assert_eq!(partners[k], k as u32 + 4);
            assert_eq!(partners[k + 4], k as u32);
        }
        assert_eq!(partners[8], 8);
        let mut lopsided = points.clone();
        lopsided[1] += Vec3::new(0.5, 0.0, 0.0);
        assert!(mirror_partners(&lopsided, 5.0).is_none());
    }
}
