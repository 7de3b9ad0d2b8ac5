//! Generated test geometry, each generator saying what it builds.
#![allow(dead_code)]

use std::sync::Arc;

use glam::Vec3;
use springwrap_kernel::{Anchor, AnchorTarget, LayoutStructure, TargetMesh, TargetMeshOptions};

/// A small deterministic generator (SplitMix64): tests must not depend on a crate or on luck.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    /// Uniform in [low, high).
    pub fn range(&mut self, low: f32, high: f32) -> f32 {
        low + (high - low) * self.unit()
    }
    pub fn below(&mut self, count: usize) -> usize {
        (self.next_u64() % count as u64) as usize
    }
    pub fn point_in_box(&mut self, half_size: f32) -> Vec3 {
        Vec3::new(
            self.range(-half_size, half_size),
            self.range(-half_size, half_size),
            self.range(-half_size, half_size),
        )
    }
}

/// A closed UV sphere of the given radius: `rings` latitude bands, `segments` longitudes.
pub fn uv_sphere(radius: f32, rings: u32, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut vertices = vec![Vec3::new(0.0, 0.0, radius)];
    for ring in 1..rings {
        let polar = std::f32::consts::PI * ring as f32 / rings as f32;
        for segment in 0..segments {
            let azimuth = std::f32::consts::TAU * segment as f32 / segments as f32;
            vertices.push(
                radius
                    * Vec3::new(
                        polar.sin() * azimuth.cos(),
                        polar.sin() * azimuth.sin(),
                        polar.cos(),
                    ),
            );
        }
    }
    vertices.push(Vec3::new(0.0, 0.0, -radius));
    let south = vertices.len() as u32 - 1;
    let ring_start = |ring: u32| 1 + (ring - 1) * segments;
    let mut triangles = Vec::new();
    for segment in 0..segments {
        let next = (segment + 1) % segments;
        triangles.push([0, ring_start(1) + segment, ring_start(1) + next]);
        triangles.push([
            south,
            ring_start(rings - 1) + next,
            ring_start(rings - 1) + segment,
        ]);
    }
    for ring in 1..rings - 1 {
        for segment in 0..segments {
            let next = (segment + 1) % segments;
            let (a, b) = (ring_start(ring) + segment, ring_start(ring) + next);
            let (c, d) = (ring_start(ring + 1) + segment, ring_start(ring + 1) + next);
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    (vertices, triangles)
}

/// A flat `size` x `size` grid of unit cells in the z = 0 plane, two triangles per cell.
pub fn grid(size: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let row = size + 1;
    let vertices = (0..row * row)
        .map(|index| Vec3::new((index % row) as f32, (index / row) as f32, 0.0))
        .collect();
    let mut triangles = Vec::new();
    for y in 0..size {
        for x in 0..size {
            let a = y * row + x;
            triangles.push([a, a + 1, a + row + 1]);
            triangles.push([a, a + row + 1, a + row]);
        }
    }
    (vertices, triangles)
}

/// A random triangle soup in a box, where about one triangle in eight is degenerate on purpose:
/// collinear corners, two equal corners, or a single point.
pub fn random_soup(rng: &mut Rng, triangle_count: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for _ in 0..triangle_count {
        let a = rng.point_in_box(5.0);
        let (b, c) = match rng.below(8) {
            0 => {
                let b = a + rng.point_in_box(1.0);
                (b, a + (b - a) * rng.range(-0.5, 1.5))
            }
            1 => (a, a + rng.point_in_box(1.0)),
            2 => (a, a),
            _ => (a + rng.point_in_box(1.0), a + rng.point_in_box(1.0)),
        };
        let base = vertices.len() as u32;
        vertices.extend([a, b, c]);
        triangles.push([base, base + 1, base + 2]);
    }
    (vertices, triangles)
}

/// A closed, lumpy egg with no symmetry ICP could slide along: a UV sphere of the given radius
/// stretched to an ellipsoid (1, 0.75, 0.55) and displaced radially by a few smooth bumps.
pub fn lumpy_egg(radius: f32, rings: u32, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (vertices, triangles) = uv_sphere(1.0, rings, segments);
    let vertices = vertices
        .into_iter()
        .map(|unit| {
            let bump = 1.0
                + 0.12 * (3.0 * unit.x + 1.0).sin() * (2.0 * unit.y).cos()
                + 0.08 * (4.0 * unit.z - 0.5).sin()
                + 0.1 * unit.x.max(0.0) * unit.y;
            radius * bump * unit * Vec3::new(1.0, 0.75, 0.55)
        })
        .collect();
    (vertices, triangles)
}

/// [`lumpy_egg`] with a hole: the triangles whose centroid has `z` above `cut` are removed.
pub fn lumpy_egg_with_hole(
    radius: f32,
    rings: u32,
    segments: u32,
    cut: f32,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (vertices, triangles) = lumpy_egg(radius, rings, segments);
    let triangles = triangles
        .into_iter()
        .filter(|triangle| {
            let centroid = triangle
                .iter()
                .map(|&corner| vertices[corner as usize])
                .sum::<Vec3>()
                / 3.0;
            centroid.z <= cut
        })
        .collect();
    (vertices, triangles)
}

/// An `n` x `n` quad grid of cell `size`, lower corner at `origin`, in the plane z = origin.z.
pub fn quad_layout(n: u32, size: f32, origin: Vec3) -> (LayoutStructure, Vec<Vec3>) {
    let row = n + 1;
    let positions = (0..row * row)
        .map(|index| {
            origin
                + Vec3::new(
                    (index % row) as f32 * size,
                    (index / row) as f32 * size,
                    0.0,
                )
        })
        .collect();
    let mut corners = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let a = y * row + x;
            corners.extend([a, a + 1, a + row + 1, a + row]);
        }
    }
    let structure = LayoutStructure::new(
        (row * row) as usize,
        &corners,
        &vec![4; (n * n) as usize],
        &[],
        &[],
    )
    .unwrap();
    (structure, positions)
}

/// A flat target: a `cells` x `cells` grid of unit cells scaled by `scale`, centred on the origin,
/// minus the cells whose centre is within `hole_radius` of the origin.
pub fn plane_target(cells: u32, scale: f32, hole_radius: f32) -> Arc<TargetMesh> {
    let (vertices, triangles) = grid(cells);
    let half = cells as f32 * 0.5;
    let vertices: Vec<Vec3> = vertices
        .iter()
        .map(|v| (*v - Vec3::new(half, half, 0.0)) * scale)
        .collect();
    let triangles: Vec<[u32; 3]> = triangles
        .into_iter()
        .filter(|corners| {
            let centre = corners.iter().map(|&i| vertices[i as usize]).sum::<Vec3>() / 3.0;
            centre.truncate().length() > hole_radius
        })
        .collect();
    Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap())
}

/// Anchors of `vertices` on the target's closest points to their `points`.
#[allow(dead_code)] // not every test binary uses every helper
pub fn anchors_at(target: &TargetMesh, points: &[Vec3], vertices: &[u32]) -> Vec<Anchor> {
    vertices
        .iter()
        .map(|&vertex| {
            let hit = target
                .closest_point(points[vertex as usize], f32::INFINITY)
                .unwrap();
            Anchor {
                vertex,
                target: AnchorTarget::Face(hit.face_point),
            }
        })
        .collect()
}

pub fn anchors_below(target: &TargetMesh, positions: &[Vec3], vertices: &[u32]) -> Vec<Anchor> {
    vertices
        .iter()
        .map(|&vertex| {
            let below = positions[vertex as usize] * Vec3::new(1.0, 1.0, 0.0);
            let hit = target.closest_point(below, f32::INFINITY).unwrap();
            Anchor {
                vertex,
                target: AnchorTarget::Face(hit.face_point),
            }
        })
        .collect()
}

/// A band of quads around the z axis (polar angles 30° to 150°), `rings` x `segments`, on an
/// ellipsoid with the given semi-axes.
pub fn band_layout(axes: Vec3, rings: u32, segments: u32) -> (LayoutStructure, Vec<Vec3>) {
    let mut positions = Vec::new();
    for ring in 0..=rings {
        let polar = (30.0 + 120.0 * ring as f32 / rings as f32).to_radians();
        for segment in 0..segments {
            let azimuth = std::f32::consts::TAU * segment as f32 / segments as f32;
            let unit = Vec3::new(
                polar.sin() * azimuth.cos(),
                polar.sin() * azimuth.sin(),
                polar.cos(),
            );
            positions.push(unit * axes);
        }
    }
    let mut corners = Vec::new();
    for ring in 0..rings {
        for segment in 0..segments {
            let a = ring * segments + segment;
            let b = ring * segments + (segment + 1) % segments;
            // Counter-clockwise seen from outside: the normals point outwards.
            corners.extend([a, a + segments, b + segments, b]);
        }
    }
    let faces = vec![4; (rings * segments) as usize];
    let structure = LayoutStructure::new(positions.len(), &corners, &faces, &[], &[]).unwrap();
    (structure, positions)
}

/// The unit sphere's band (`rings` x `segments`, see [`band_layout`]) and the target it should
/// wrap onto: the sphere (64 x 128) stretched by `axes`, four anchors on the band's equator at
/// their true places. Returns the target, the band's structure, its unit directions (where it
/// starts), the truth (each direction scaled by `axes`) and the anchors.
pub fn stretched_band(
    axes: Vec3,
    rings: u32,
    segments: u32,
) -> (
    Arc<TargetMesh>,
    LayoutStructure,
    Vec<Vec3>,
    Vec<Vec3>,
    Vec<Anchor>,
) {
    let (vertices, triangles) = uv_sphere(1.0, 64, 128);
    let vertices = vertices.into_iter().map(|v| v * axes).collect();
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let (structure, directions) = band_layout(Vec3::ONE, rings, segments);
    let truth: Vec<Vec3> = directions.iter().map(|&d| d * axes).collect();
    let equator = rings / 2 * segments;
    let quarters: Vec<u32> = (0..4).map(|q| equator + q * segments / 4).collect();
    let anchors = anchors_at(&target, &truth, &quarters);
    (target, structure, directions, truth, anchors)
}
