//! Four triangles at a time: a branch-free SIMD estimate of the squared distance from a point to
//! each, used to skip the exact (branchy) closest-point test on triangles that cannot win.
//!
//! The estimate is the exact distance up to rounding (the projection onto the plane when it falls
//! inside the triangle, else the nearest of the three edges), or smaller (a projection just
//! outside the triangle counts as inside); for slivers and degenerate triangles, whose
//! barycentric coordinates round badly, it is zero, so they are always tested exactly.

use glam::{Vec3A, Vec4};

/// A projection at most this far outside the triangle, in barycentric coordinates, counts as
/// inside (its distance to the plane is still a lower bound): far more than the rounding of the
/// barycentric coordinates of a triangle that is not a sliver.
const INSIDE_TOLERANCE: f32 = 1e-3;

/// A triangle whose widest angle has a `sin²` below this is a sliver (a cap, nearly flat): the
/// barycentric coordinates, taken from that corner, lose up to `1 / SLIVER_SIN_SQUARED` times
/// the float precision.
const SLIVER_SIN_SQUARED: f32 = 1e-2;

/// Four triangles in structure-of-arrays form, with the reciprocals that do not depend on the
/// query point (the dot products of the edges are recomputed per query: cheaper than their
/// bytes). Lane `i` is the triangle in BVH slot `first_slot + i` (its corners possibly rotated:
/// the estimate does not depend on which corner comes first); unused lanes are NaN.
///
/// 224 bytes (four triangles' corner and edges, 4 reciprocals, the first slot).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct TrianglePacket {
    /// Corner 0, per axis.
    a: [Vec4; 3],
    /// Edge from corner 0 to corner 1, per axis.
    e0: [Vec4; 3],
    /// Edge from corner 0 to corner 2, per axis.
    e1: [Vec4; 3],
    /// `1 / (d00 d11 - d01²)` (the edges' dot products); 0 for triangles to test exactly
    /// whatever the estimate (slivers, degenerate).
    inv_denominator: Vec4,
    /// `1 / |e0|²`, `1 / |e1|²`, `1 / |e1 - e0|²` (0 for a zero-length edge).
    inv_edge_lengths: [Vec4; 3],
    /// The BVH slot of lane 0; the lanes are consecutive slots.
    pub(crate) first_slot: u32,
}

impl TrianglePacket {
    /// A packet of up to four triangles of consecutive slots: `(slot, corners, degenerate)`.
    pub(crate) fn new(triangles: &[(u32, [Vec3A; 3], bool)]) -> Self {
        assert!(
            (1..=4).contains(&triangles.len()),
            "a packet holds one to four triangles"
        );
        let first_slot = triangles[0].0;
        let mut lanes = [[f32::NAN; 13]; 4];
        for (lane, &(slot, corners, degenerate)) in triangles.iter().enumerate() {
            assert_eq!(
                slot,
                first_slot + lane as u32,
                "a packet's slots are consecutive"
            );
            // From the corner of the widest angle (opposite the longest edge), the basis of the
            // barycentric coordinates is as well conditioned as the triangle allows.
            let [a, b, c] = corners;
            let [a, b, c] = if (c - b).length_squared()
                >= (b - a).length_squared().max((c - a).length_squared())
            {
                [a, b, c]
            } else if (c - a).length_squared() >= (b - a).length_squared() {
                [b, c, a]
            } else {
                [c, a, b]
            };
            let e0 = b - a;
            let e1 = c - a;
            let e2 = c - b;
            let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
            let denominator = d00 * d11 - d01 * d01;
            // (Written so that a NaN, from coordinates near overflow, counts as a sliver.)
            let well_shaped = denominator > SLIVER_SIN_SQUARED * d00 * d11;
            let sliver = degenerate || !well_shaped;
            let inverse = |length_squared: f32| {
                if length_squared > 0.0 {
                    1.0 / length_squared
                } else {
                    0.0
                }
            };
            lanes[lane] = [
                a.x,
                a.y,
                a.z,
                e0.x,
                e0.y,
                e0.z,
                e1.x,
                e1.y,
                e1.z,
                if sliver { 0.0 } else { 1.0 / denominator },
                inverse(d00),
                inverse(d11),
                inverse(e2.length_squared()),
            ];
        }
        let column = |index: usize| {
            Vec4::new(
                lanes[0][index],
                lanes[1][index],
                lanes[2][index],
                lanes[3][index],
            )
        };
        Self {
            a: [column(0), column(1), column(2)],
            e0: [column(3), column(4), column(5)],
            e1: [column(6), column(7), column(8)],
            inv_denominator: column(9),
            inv_edge_lengths: [column(10), column(11), column(12)],
            first_slot,
        }
    }

    /// Estimated squared distances from the point `(x, y, z)` (each splatted) to the four
    /// triangles: within rounding of the exact distance, or below it (see the module's text);
    /// `+inf` for unused lanes.
    // The edges are named after their corners (ab, ac, bc), names a letter apart.
    #[allow(clippy::similar_names)]
    #[inline(always)]
    pub(crate) fn distances_squared(&self, x: Vec4, y: Vec4, z: Vec4) -> Vec4 {
        let [e0x, e0y, e0z] = self.e0;
        let [e1x, e1y, e1z] = self.e1;
        let apx = x - self.a[0];
        let apy = y - self.a[1];
        let apz = z - self.a[2];
        let d00 = e0x * e0x + e0y * e0y + e0z * e0z;
        let d01 = e0x * e1x + e0y * e1y + e0z * e1z;
        let d11 = e1x * e1x + e1y * e1y + e1z * e1z;
        let d20 = apx * e0x + apy * e0y + apz * e0z;
        let d21 = apx * e1x + apy * e1y + apz * e1z;
        // Barycentric coordinates of the projection onto the plane.
        let v = (d11 * d20 - d01 * d21) * self.inv_denominator;
        let w = (d00 * d21 - d01 * d20) * self.inv_denominator;
        let tolerance = Vec4::splat(-INSIDE_TOLERANCE);
        let inside = v.cmpge(tolerance) & w.cmpge(tolerance) & (Vec4::ONE - v - w).cmpge(tolerance);
        let interior = {
            let qx = apx - v * e0x - w * e1x;
            let qy = apy - v * e0y - w * e1y;
            let qz = apz - v * e0z - w * e1z;
            qx * qx + qy * qy + qz * qz
        };
        // The three edges as segments: a→b, a→c, b→c.
        let [inv_ab, inv_ac, inv_bc] = self.inv_edge_lengths;
        let along_ab = (d20 * inv_ab).clamp(Vec4::ZERO, Vec4::ONE);
        let edge_ab = {
            let rx = apx - along_ab * e0x;
            let ry = apy - along_ab * e0y;
            let rz = apz - along_ab * e0z;
            rx * rx + ry * ry + rz * rz
        };
        let along_ac = (d21 * inv_ac).clamp(Vec4::ZERO, Vec4::ONE);
        let edge_ac = {
            let rx = apx - along_ac * e1x;
            let ry = apy - along_ac * e1y;
            let rz = apz - along_ac * e1z;
            rx * rx + ry * ry + rz * rz
        };
        // (p - b) · (c - b) = (d21 - d20) - (d01 - d00).
        let along_bc = (((d21 - d20) - (d01 - d00)) * inv_bc).clamp(Vec4::ZERO, Vec4::ONE);
        let edge_bc = {
            let bpx = apx - e0x;
            let bpy = apy - e0y;
            let bpz = apz - e0z;
            let rx = bpx - along_bc * (e1x - e0x);
            let ry = bpy - along_bc * (e1y - e0y);
            let rz = bpz - along_bc * (e1z - e0z);
            rx * rx + ry * ry + rz * rz
        };
        let edges = edge_ab.min(edge_ac).min(edge_bc);
        // Slivers and degenerate triangles (a zero reciprocal) estimate 0; `min` returns its
        // second operand when the first is NaN, so unused lanes (NaN) give `+inf`.
        let floor = Vec4::select(
            self.inv_denominator.cmpeq(Vec4::ZERO),
            Vec4::ZERO,
            Vec4::INFINITY,
        );
        Vec4::select(inside, interior, edges).min(floor)
    }
}
