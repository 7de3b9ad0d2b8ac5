//! Times an energy wrap read from raw files, phase by phase, in processor seconds:
//! `cargo run --release -p springwrap-kernel --example wrap_profile -- CASE ANCHORS [RUNS]`
//! (`benchmarks/wrap_case_files.py CASE ANCHORS` writes the body of `benchmarks/wrap_speed.py`:
//! `CASE/target_vertices.f32`, `target_triangles.u32`, `quads.u32` and, in `CASE/aANCHORS/`,
//! `aligned.f32`, `anchor_vertices.u32`, `anchor_triangles.u32`, `anchor_barycentrics.f32`; the
//! layout starts as space-points at `aligned`, its rest shape too, anchored as face-points).
//! Prints each run's phases, its processor and wall seconds and a checksum of the positions (the
//! same for a change that keeps the result); `PER_ITERATION=1` also prints each iteration's
//! correspondences, solve and safeguard seconds; `WALL=1` times the phases in wall seconds.

use std::fmt::Write;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use springwrap_kernel::{
    Anchor, AnchorTarget, FacePoint, LayoutPoint, LayoutStructure, TargetMesh, TargetMeshOptions,
    WrapPhase, WrapSettings, WrapSolver,
};

fn words(path: &Path) -> Vec<[u8; 4]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytes
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect()
}

fn floats(path: &Path) -> Vec<f32> {
    words(path).into_iter().map(f32::from_le_bytes).collect()
}

fn integers(path: &Path) -> Vec<u32> {
    words(path).into_iter().map(u32::from_le_bytes).collect()
}

fn vectors(path: &Path) -> Vec<Vec3> {
    floats(path)
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect()
}

/// The processor seconds of all the process's threads so far.
fn processor_seconds() -> f64 {
    std::fs::read_dir("/proc/self/task").map_or(0.0, |tasks| {
        tasks
            .filter_map(|task| {
                let statistics =
                    std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
                statistics.split_whitespace().next()?.parse::<u64>().ok()
            })
            .sum::<u64>() as f64
            * 1e-9
    })
}

/// Wall seconds since the first call (`WALL=1`: the phases in wall time, to see which ones use
/// one core only when set beside a processor-time run).
fn wall_seconds() -> f64 {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_secs_f64()
}

fn main() {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    let case = Path::new(&arguments[0]);
    let anchors_dir = case.join(format!("a{}", arguments[1]));
    let runs: usize = arguments.get(2).map_or(1, |a| a.parse().expect("RUNS"));
    let vertices = vectors(&case.join("target_vertices.f32"));
    let triangles: Vec<[u32; 3]> = integers(&case.join("target_triangles.u32"))
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let quads = integers(&case.join("quads.u32"));
    let aligned = vectors(&anchors_dir.join("aligned.f32"));
    let anchor_vertices = integers(&anchors_dir.join("anchor_vertices.u32"));
    let anchor_triangles = integers(&anchors_dir.join("anchor_triangles.u32"));
    let anchor_barycentrics = vectors(&anchors_dir.join("anchor_barycentrics.f32"));
    let anchors: Vec<Anchor> = (0..anchor_vertices.len())
        .map(|i| Anchor {
            vertex: anchor_vertices[i],
            target: AnchorTarget::Face(FacePoint {
                triangle: anchor_triangles[i],
                barycentric: anchor_barycentrics[i],
            }),
        })
        .collect();
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let structure =
        LayoutStructure::new(aligned.len(), &quads, &vec![4; quads.len() / 4], &[], &[]).unwrap();
    // Warm the target's trees (built lazily) so the wrap's times do not include them.
    let _ = target.closest_point(aligned[0], f32::INFINITY);
    let mut totals = Vec::new();
    for run in 0..runs {
        let points = aligned.iter().map(|&p| LayoutPoint::Space(p)).collect();
        let mut solver = WrapSolver::with_rest_shape(
            Arc::clone(&target),
            structure.clone(),
            points,
            Some(aligned.clone()),
            &anchors,
            WrapSettings::default(),
        )
        .unwrap();
        solver.profile_with(if std::env::var_os("WALL").is_some() {
            wall_seconds
        } else {
            processor_seconds
        });
        let (wall, processor) = (Instant::now(), processor_seconds());
        let per_iteration = std::env::var_os("PER_ITERATION").is_some();
        let report = if per_iteration {
            let mut last = solver.phase_times();
            let mut last_statistics = solver.solve_statistics();
            loop {
                let report = solver.step(1).unwrap();
                let now = solver.phase_times();
                let statistics = solver.solve_statistics();
                println!(
                    "  iteration {}: correspondences {:.4} solve {:.4} ({} factored, {} cg) safeguard {:.4} max move {:.2e} held {}",
                    report.total_iterations,
                    now.seconds(WrapPhase::Correspondences)
                        - last.seconds(WrapPhase::Correspondences),
                    now.seconds(WrapPhase::Solve) - last.seconds(WrapPhase::Solve),
                    statistics.factorizations - last_statistics.factorizations,
                    statistics.iterations - last_statistics.iterations,
                    now.seconds(WrapPhase::Safeguard) - last.seconds(WrapPhase::Safeguard),
                    report.max_displacement,
                    report.held_back
                );
                (last, last_statistics) = (now, statistics);
                if report.converged {
                    break report;
                }
            }
        } else {
            solver.step(WrapSettings::MAX_STEP_ITERATIONS).unwrap()
        };
        let (wall, processor) = (
            wall.elapsed().as_secs_f64(),
            processor_seconds() - processor,
        );
        let times = solver.phase_times();
        let mut line = format!("run {run}:");
        for phase in WrapPhase::ALL {
            let _ = write!(line, " {} {:.3}", phase.name(), times.seconds(phase));
        }
        println!("{line}");
        let checksum: f64 = solver
            .positions()
            .iter()
            .map(|p| f64::from(p.x) + 3.0 * f64::from(p.y) + 7.0 * f64::from(p.z))
            .sum();
        let statistics = solver.solve_statistics();
        println!(
            "run {run}: {:.3} processor s, {:.3} wall s, {} iterations, converged {}, {} factorizations, {} cg iterations, checksum {checksum:.9}",
            processor,
            wall,
            report.total_iterations,
            report.converged,
            statistics.factorizations,
            statistics.iterations
        );
        totals.push(processor);
    }
    totals.sort_by(f64::total_cmp);
    println!(
        "processor s: min {:.3} median {:.3} max {:.3}",
        totals[0],
        totals[totals.len() / 2],
        totals[totals.len() - 1]
    );
}
