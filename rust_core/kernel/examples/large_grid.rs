//! Times the energy wrap of a dense torus grid, phase by phase:
//! `cargo run --release -p springwrap-kernel --example large_grid -- [SIDE] [ITERATIONS]`
//! (a layout of about SIDE² points on a noisy torus of about SIDE²/4 triangles, started on its
//! surface; `--help` says more).

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use springwrap_kernel::{
    LayoutFaces, LayoutPoint, LayoutStructure, TargetMesh, TargetMeshOptions, WrapPhase,
    WrapSettings, WrapSolver, layout_readout,
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

const HELP: &str = "\
large_grid [SIDE] [ITERATIONS]: wraps a layout of about SIDE x SIDE points (default 1024) on a
noisy torus of about SIDE^2/4 triangles for at most ITERATIONS iterations (default: until the
wrap converges), then prints the seconds of each phase of the energy solver and of the whole
wrap, in processor time (all threads, from /proc/self/task/*/schedstat; wall time where that
cannot be read) and in wall time, the global step's solves (factorizations, conjugate-gradient
iterations), the peak resident memory, and the result's quality: the distance of the points to
the target, the stretch of the layout against its rest shape and the faces flipped.";

/// The processor seconds of all the process's threads so far (their scheduler statistics), or
/// the wall seconds since the first call where those cannot be read.
fn processor_seconds() -> f64 {
    let threads = std::fs::read_dir("/proc/self/task").ok().map(|tasks| {
        tasks
            .filter_map(|task| {
                let statistics =
                    std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
                statistics.split_whitespace().next()?.parse::<u64>().ok()
            })
            .sum::<u64>()
    });
    match threads {
        Some(nanoseconds) if nanoseconds > 0 => nanoseconds as f64 * 1e-9,
        _ => wall_seconds(),
    }
}

/// Wall seconds since the first call.
fn wall_seconds() -> f64 {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_secs_f64()
}

/// The peak resident memory of the process in GB, if the system says.
fn peak_memory_gb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|line| line.starts_with("VmHWM:"))?;
    let kilobytes: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kilobytes / 1e6)
}

fn main() {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    if arguments.iter().any(|a| a == "--help" || a == "-h") {
        println!("{HELP}");
        return;
    }
    let side: u32 = arguments.first().map_or(1024, |a| a.parse().expect("SIDE"));
    let iterations: usize = arguments
        .get(1)
        .map_or(WrapSettings::MAX_STEP_ITERATIONS, |a| {
            a.parse().expect("ITERATIONS")
        });
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
    let mut solver = WrapSolver::with_rest_shape(
        Arc::clone(&target),
        structure,
        points,
        Some(rest.clone()),
        &[],
        WrapSettings::default(),
    )
    .unwrap();
    solver.profile_with(processor_seconds);
    let (wrap, wrap_processor) = (Instant::now(), processor_seconds());
    let mut report = None;
    for _ in 0..iterations {
        let step = Instant::now();
        let before = solver.solve_statistics().iterations;
        let step_report = solver.step(1).unwrap();
        println!(
            "iteration {}: {:.2} s, {} solve iterations, energy {:.6e}, mean move {:.3e}, \
             held back {}, converged {}",
            step_report.total_iterations,
            step.elapsed().as_secs_f64(),
            solver.solve_statistics().iterations - before,
            step_report.energy,
            step_report.mean_displacement,
            step_report.held_back,
            step_report.converged
        );
        report = Some(step_report);
        if step_report.converged {
            break;
        }
    }
    let (wall, processor) = (
        wrap.elapsed().as_secs_f64(),
        processor_seconds() - wrap_processor,
    );
    let statistics = solver.solve_statistics();
    println!(
        "solves {}, factorizations {}, conjugate-gradient iterations {}",
        statistics.solves, statistics.factorizations, statistics.iterations
    );
    let times = solver.phase_times();
    println!("phase            processor s");
    for phase in WrapPhase::ALL {
        println!("{:<16} {:>11.2}", phase.name(), times.seconds(phase));
    }
    println!("{:<16} {:>11.2}", "phases", times.total());
    println!(
        "wrap: {:.2} processor s, {:.2} wall s, {} iterations, converged {}, peak memory {} GB",
        processor,
        wall,
        report.map_or(0, |report| report.total_iterations),
        report.is_some_and(|report| report.converged),
        peak_memory_gb().map_or_else(|| "?".to_string(), |gb| format!("{gb:.2}")),
    );
    print_quality(&solver, &target, &rest, &corners);
}

/// The distances of the wrapped points to the target, the stretch against the rest shape and the
/// flipped faces (measured after the timings).
fn print_quality(solver: &WrapSolver, target: &TargetMesh, rest: &[Vec3], corners: &[u32]) {
    let positions = solver.positions();
    let distances: Vec<f64> = positions
        .par_iter()
        .map(|&p| {
            target
                .closest_point(p, f32::INFINITY)
                .map_or(f64::INFINITY, |hit| f64::from(hit.distance))
        })
        .collect();
    let count = positions.len() as f64;
    let points: Vec<_> = positions.iter().map(|p| p.as_dvec3()).collect();
    let rest: Vec<_> = rest.iter().map(|p| p.as_dvec3()).collect();
    let sizes = vec![4; corners.len() / 4];
    let edges: Vec<[u32; 2]> = corners
        .chunks(4)
        .flat_map(|quad| [[quad[0], quad[1]], [quad[1], quad[2]]])
        .collect();
    let faces = LayoutFaces {
        corners,
        sizes: &sizes,
    };
    let readout = layout_readout(&points, Some(&rest), faces, &edges).unwrap();
    let deviation: Vec<f64> = readout.stretch.iter().map(|s| s.ln().abs()).collect();
    println!(
        "quality: distance mean {:.4e} max {:.4e}; |log stretch| mean {:.4e} max {:.4e}; \
         flipped faces {}",
        distances.iter().sum::<f64>() / count,
        distances.iter().copied().fold(0.0, f64::max),
        deviation.iter().sum::<f64>() / count,
        deviation.iter().copied().fold(0.0, f64::max),
        readout.flipped.iter().filter(|&&flipped| flipped).count(),
    );
}
