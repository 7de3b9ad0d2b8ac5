//! Kernel-only throughput of the target-mesh build and the queries, on a bumpy sphere of about
//! 1M triangles (`cargo bench -p springwrap-kernel`; `-- --triangles N` to resize).
//!
//! Query points sit a little off the surface, in mesh-vertex order ("coherent") and shuffled
//! ("random"). Not a test: it prints a table. `make bench` runs the full comparison with Blender.

use std::time::Instant;

use glam::Vec3;
use springwrap_kernel::{TargetMesh, TargetMeshOptions};

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn signed(&mut self) -> f32 {
        self.unit() * 2.0 - 1.0
    }
}

/// A cube sphere of `6 * 2 * n^2` triangles with bumps of 2% of the radius.
fn bumpy_sphere(n: u32, rng: &mut Rng) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let base = vertices.len() as u32;
            for i in 0..=n {
                for j in 0..=n {
                    let mut p = Vec3::ZERO;
                    p[axis] = sign;
                    p[(axis + 1) % 3] = -1.0 + 2.0 * i as f32 / n as f32;
                    p[(axis + 2) % 3] = -1.0 + 2.0 * j as f32 / n as f32;
                    vertices.push(p.normalize() * (1.0 + 0.02 * rng.signed()));
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let a = base + i * (n + 1) + j;
                    let (b, c, d) = (a + n + 1, a + n + 2, a + 1);
                    triangles.push([a, b, c]);
                    triangles.push([a, c, d]);
                }
            }
        }
    }
    (vertices, triangles)
}

fn rate(count: usize, seconds: f64) -> String {
    format!("{:>8.0}k/s", count as f64 / seconds / 1e3)
}

fn main() {
    let arguments: Vec<String> = std::env::args().collect();
    let triangles_wanted: f64 = arguments
        .iter()
        .position(|argument| argument == "--triangles")
        .and_then(|index| arguments.get(index + 1))
        .and_then(|value| value.parse().ok())
        .unwrap_or(1_000_000.0);
    let n = (triangles_wanted / 12.0).sqrt().round() as u32;
    let mut rng = Rng(42);
    let (vertices, triangles) = bumpy_sphere(n, &mut rng);
    let edge = 2.0 / n as f32;
    let queries: Vec<Vec3> = vertices
        .iter()
        .map(|v| *v + Vec3::new(rng.signed(), rng.signed(), rng.signed()) * edge)
        .collect();
    let mut shuffled = queries.clone();
    for index in (1..shuffled.len()).rev() {
        shuffled.swap(index, (rng.next() % (index as u64 + 1)) as usize);
    }
    let triangle_count = triangles.len();
    let start = Instant::now();
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let build = start.elapsed().as_secs_f64();
    let start = Instant::now();
    mesh.prepare_all();
    let prepare = start.elapsed().as_secs_f64();
    println!(
        "{triangle_count} triangles, {} queries, {} threads",
        queries.len(),
        rayon::current_num_threads()
    );
    println!("build (face tree) {build:.3} s; vertex tree + topology + normals {prepare:.3} s");
    for (order, points) in [("coherent", &queries), ("random", &shuffled)] {
        let start = Instant::now();
        let hits = mesh.closest_points(points, f32::INFINITY).unwrap();
        let closest = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let vertex_hits = mesh.nearest_vertices(points, f32::INFINITY).unwrap();
        let nearest = start.elapsed().as_secs_f64();
        let directions: Vec<Vec3> = points.iter().map(|p| -*p).collect();
        let start = Instant::now();
        let ray_hits = mesh
            .ray_casts(points, &directions, f32::INFINITY, true)
            .unwrap();
        let rays = start.elapsed().as_secs_f64();
        assert!(hits.iter().all(Option::is_some) && vertex_hits.iter().all(Option::is_some));
        assert!(ray_hits.iter().filter(|hit| hit.is_some()).count() > points.len() * 9 / 10);
        println!(
            "{order:>9}: closest point {}  nearest vertex {}  ray cast (both ways) {}",
            rate(points.len(), closest),
            rate(points.len(), nearest),
            rate(points.len(), rays)
        );
    }
}
