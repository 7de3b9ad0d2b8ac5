//! Times the energy wrap of a dense torus grid: `cargo run --release --example large_grid -- SIDE [ITERATIONS]`
//! (a layout of about SIDE² points on a noisy torus of about SIDE²/4 triangles, started on its surface).

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use springwrap_kernel::{
    LayoutPoint, LayoutStructure, TargetMesh, TargetMeshOptions, WrapSettings, WrapSolver,
};

const MAJOR: f32 = 1.0;
const MINOR: f32 = 0.3;

fn torus(major: u32, minor: u32, bump: f32) -> (Vec<Vec3>, Vec<u32>) {
    let mut vertices = Vec::with_capacity((major * minor) as usize);
    for i in 0..major {
        for j in 0..minor {
            let u = i as f32 / major as f32 * std::f32::consts::TAU;
            let v = j as f32 / minor as f32 * std::f32::consts::TAU;
            let r = MINOR
                + bump
                    * ((7.0 * u + 1.0).sin() * (3.0 * v + 0.5).cos()
                        + 0.5 * (13.0 * u - 5.0 * v).sin());
            let normal = Vec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
            vertices.push(Vec3::new(MAJOR * u.cos(), MAJOR * u.sin(), 0.0) + normal * r);
        }
    }
    let mut quads = Vec::with_capacity(4 * (major * minor) as usize);
    for i in 0..major {
        for j in 0..minor {
            let (i1, j1) = ((i + 1) % major, (j + 1) % minor);
            quads.extend([
                i * minor + j,
                i1 * minor + j,
                i1 * minor + j1,
                i * minor + j1,
            ]);
        }
    }
    (vertices, quads)
}

fn main() {
    let mut arguments = std::env::args().skip(1);
    let side: u32 = arguments.next().map_or(1024, |a| a.parse().unwrap());
    let iterations: usize = arguments.next().map_or(3, |a| a.parse().unwrap());
    let start = Instant::now();
    let cells = side * side / 4;
    let minor_t = ((cells as f32 / 3.33).sqrt()) as u32;
    let major_t = cells / minor_t;
    let (target_vertices, quads) = torus(major_t, minor_t, 0.02);
    let triangles: Vec<[u32; 3]> = quads
        .chunks(4)
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    let target = Arc::new(
        TargetMesh::new(target_vertices, triangles, TargetMeshOptions::default()).unwrap(),
    );
    let minor = ((side * side) as f32 / 3.33).sqrt() as u32;
    let major = side * side / minor;
    let (rest, corners) = torus(major, minor, 0.0);
    let structure =
        LayoutStructure::new(rest.len(), &corners, &vec![4; corners.len() / 4], &[], &[]).unwrap();
    let points: Vec<LayoutPoint> = rest
        .par_iter()
        .map(|&p| match target.closest_point(p, 1.0) {
            Some(hit) => LayoutPoint::Face(hit.face_point),
            None => LayoutPoint::Space(p),
        })
        .collect();
    println!(
        "{} points, {} target triangles: built in {:.2} s",
        rest.len(),
        target.triangles().len(),
        start.elapsed().as_secs_f64()
    );
    let build = Instant::now();
    let mut solver = WrapSolver::with_rest_shape(
        target,
        structure,
        points,
        Some(rest),
        &[],
        WrapSettings::default(),
    )
    .unwrap();
    println!("solver made in {:.2} s", build.elapsed().as_secs_f64());
    let wrap = Instant::now();
    for _ in 0..iterations {
        let step = Instant::now();
        let report = solver.step(1).unwrap();
        println!(
            "iteration {}: {:.2} s, mean move {:.3e}, held back {}, converged {}",
            report.total_iterations,
            step.elapsed().as_secs_f64(),
            report.mean_displacement,
            report.held_back,
            report.converged
        );
        if report.converged {
            break;
        }
    }
    println!("wrap {:.2} s", wrap.elapsed().as_secs_f64());
}
