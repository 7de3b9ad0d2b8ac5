//! Times a dense target's build, and says how much of it runs on one thread:
//! `cargo run --release -p springwrap-kernel --example target_build -- [MILLION_TRIANGLES]`
//! (a noisy torus of about that many million triangles, default 2).
//!
//! Prints, for `TargetMesh::new` (validation, the face tree) and for `prepare_all` (the other
//! trees, adjacency, normals): the wall seconds, the processor seconds of all threads, and those
//! of the calling thread alone. Rayon's calling thread waits while the pool works, so its own
//! processor time is the build's serial part: on a busy machine the wall clock says more about the
//! others, the split says what two quiet cores would do (wall at least serial + parallel / 2).

use std::time::Instant;

use glam::Vec3;
use springwrap_kernel::{TargetMesh, TargetMeshOptions};

fn torus(major: u32, minor: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut vertices = Vec::with_capacity((major * minor) as usize);
    for i in 0..major {
        for j in 0..minor {
            let u = i as f32 / major as f32 * std::f32::consts::TAU;
            let v = j as f32 / minor as f32 * std::f32::consts::TAU;
            let r = 0.3 + 0.02 * ((7.0 * u + 1.0).sin() * (3.0 * v + 0.5).cos());
            let normal = Vec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
            vertices.push(Vec3::new(u.cos(), u.sin(), 0.0) + normal * r);
        }
    }
    let mut triangles = Vec::with_capacity(2 * (major * minor) as usize);
    for i in 0..major {
        for j in 0..minor {
            let (i1, j1) = ((i + 1) % major, (j + 1) % minor);
            let [a, b, c, d] = [
                i * minor + j,
                i1 * minor + j,
                i1 * minor + j1,
                i * minor + j1,
            ];
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    (vertices, triangles)
}

/// Processor seconds of (all threads, the calling thread), from the scheduler's statistics.
fn processor_seconds() -> (f64, f64) {
    let read = |path: std::path::PathBuf| -> Option<f64> {
        let text = std::fs::read_to_string(path.join("schedstat")).ok()?;
        Some(text.split_whitespace().next()?.parse::<u64>().ok()? as f64 * 1e-9)
    };
    let all = std::fs::read_dir("/proc/self/task").map_or(0.0, |tasks| {
        tasks.filter_map(|task| read(task.ok()?.path())).sum()
    });
    let own = read(std::path::PathBuf::from("/proc/thread-self")).unwrap_or(0.0);
    (all, own)
}

fn measure(what: &str, triangles: usize, run: impl FnOnce()) {
    let (wall, (all, own)) = (Instant::now(), processor_seconds());
    run();
    let wall = wall.elapsed().as_secs_f64();
    let (all_after, own_after) = processor_seconds();
    let (total, serial) = (all_after - all, own_after - own);
    let million = triangles as f64 * 1e-6;
    println!(
        "{what:<12} wall {wall:.2} s ({:.3} s/M), processor {total:.2} s ({:.3} s/M), \
         serial {serial:.2} s ({:.0} %); two quiet cores: at least {:.3} s/M",
        wall / million,
        total / million,
        100.0 * serial / total.max(1e-9),
        (serial + (total - serial) / 2.0) / million,
    );
}

fn main() {
    let million: f64 = std::env::args()
        .nth(1)
        .map_or(2.0, |a| a.parse().expect("MILLION_TRIANGLES"));
    let cells = (million * 1e6 / 2.0) as u32;
    let minor = ((cells as f32 / 3.33).sqrt()) as u32;
    let (vertices, triangles) = torus(cells / minor, minor);
    let count = triangles.len();
    println!(
        "{count} triangles, {} threads",
        rayon::current_num_threads()
    );
    let mut mesh = None;
    measure("build", count, || {
        mesh = Some(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    });
    let mesh = mesh.expect("built");
    measure("prepare_all", count, || mesh.prepare_all());
}
