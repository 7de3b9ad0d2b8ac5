//! Kernel-only cost of the quality read-out (`layout_readout`: stretch, flipped faces, the layout's
//! size) on a quad torus of about 1M vertices (`cargo bench -p springwrap-kernel --bench readout`;
//! `-- --vertices N` to resize, `-- --repeat N` for more runs).
//!
//! The layout now is its rest shape turned, bent and a little noisy, with a few faces folded over:
//! the read-out's usual case (almost nothing flipped) with some work for the flip test. Not a
//! test: it prints the best wall and processor time of each call (processor time over all
//! threads, what other work on the machine skews least). `make bench` measures the read-out
//! inside the snap operator (`benchmarks/snap_throughput.py`).

use std::time::Instant;

use glam::DVec3;
use springwrap_kernel::{LayoutFaces, face_normals, flipped_faces, layout_readout, vertex_stretch};

/// Numbers uniform in [-1, 1) from a linear congruential generator.
fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// Rest positions, positions now, face corners, face sizes, edges.
type Layout = (Vec<DVec3>, Vec<DVec3>, Vec<u32>, Vec<u32>, Vec<[u32; 2]>);

/// A quad torus of `rows x columns` vertices: (rest positions, positions now, corners, sizes,
/// edges). Now: the rest shape bent about the torus's axis, turned, moved and jittered by 5 % of an
/// edge, with one face in 2,000 folded over (its first corner pushed through the face).
fn torus(rows: u32, columns: u32) -> Layout {
    let mut random = uniform(7);
    let (mut rest, mut now) = (Vec::new(), Vec::new());
    let turn = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.8);
    let edge = std::f64::consts::TAU / f64::from(columns);
    for row in 0..rows {
        let major = std::f64::consts::TAU * f64::from(row) / f64::from(rows);
        for column in 0..columns {
            let minor = std::f64::consts::TAU * f64::from(column) / f64::from(columns);
            let point = |major: f64, radius: f64| {
                let around = 3.0 + radius * minor.cos();
                DVec3::new(
                    around * major.cos(),
                    around * major.sin(),
                    radius * minor.sin(),
                )
            };
            rest.push(point(major, 1.0));
            let jitter = DVec3::new(random(), random(), random()) * 0.05 * edge;
            now.push(turn * point(major * 0.9, 1.0 + 0.2 * major.sin()) + jitter + 100.0);
        }
    }
    let index = |row: u32, column: u32| (row % rows) * columns + column % columns;
    let (mut corners, mut sizes, mut edges) = (Vec::new(), Vec::new(), Vec::new());
    for row in 0..rows {
        for column in 0..columns {
            corners.extend([
                index(row, column),
                index(row, column + 1),
                index(row + 1, column + 1),
                index(row + 1, column),
            ]);
            sizes.push(4);
            edges.push([index(row, column), index(row, column + 1)]);
            edges.push([index(row, column), index(row + 1, column)]);
        }
    }
    for face in (0..sizes.len()).step_by(2000) {
        let face_corners = &corners[4 * face..4 * face + 4];
        let centre = face_corners
            .iter()
            .map(|&vertex| now[vertex as usize])
            .sum::<DVec3>()
            / 4.0;
        let first = face_corners[0] as usize;
        now[first] = centre + (centre - now[first]) * 1.5;
    }
    (rest, now, corners, sizes, edges)
}

fn best<T>(repeat: usize, mut work: impl FnMut() -> T) -> (f64, f64, T) {
    let (mut wall, mut processor) = (f64::INFINITY, f64::INFINITY);
    let mut last = None;
    for _ in 0..repeat {
        let (start, start_processor) = (Instant::now(), processor_seconds());
        last = Some(work());
        wall = wall.min(start.elapsed().as_secs_f64());
        processor = processor.min(processor_seconds() - start_processor);
    }
    (wall, processor, last.expect("at least one run"))
}

/// The process's processor time over all its threads (user and system), from /proc (0 elsewhere).
fn processor_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command's closing parenthesis: utime and stime are the 12th and 13th.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or("", |(_, rest)| rest)
        .split_whitespace()
        .collect();
    let ticks = |index: usize| {
        fields
            .get(index)
            .and_then(|value| value.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let arguments: Vec<String> = std::env::args().collect();
    let option = |name: &str, default: usize| {
        arguments
            .iter()
            .position(|argument| argument == name)
            .and_then(|at| arguments.get(at + 1))
            .and_then(|value| value.parse().ok())
            .unwrap_or(default)
    };
    let (vertices, repeat) = (option("--vertices", 1_000_000), option("--repeat", 5));
    let rows = ((vertices as f64 / 2.0).sqrt().round() as u32).max(3);
    let columns = (vertices as u32 / rows).max(3);
    let (rest, now, corners, sizes, edges) = torus(rows, columns);
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    println!(
        "layout: quad torus, {} vertices, {} faces, {} edges; best of {repeat}; threads {}",
        now.len(),
        sizes.len(),
        edges.len(),
        rayon::current_num_threads()
    );
    let report = |name: &str, (wall, processor): (f64, f64)| {
        println!("{name:<28} {wall:>8.3} s wall {processor:>8.3} s processor");
    };
    let (wall, processor, readout) = best(repeat, || {
        layout_readout(&now, Some(&rest), faces, &edges).expect("valid layout")
    });
    report("layout_readout", (wall, processor));
    let (wall, processor, flipped) = best(repeat, || {
        flipped_faces(&now, &rest, faces, &edges).expect("valid layout")
    });
    report("flipped_faces", (wall, processor));
    let (wall, processor, _) = best(repeat, || {
        vertex_stretch(&now, &rest, &edges).expect("valid layout")
    });
    report("vertex_stretch", (wall, processor));
    let (wall, processor, _) = best(repeat, || face_normals(&now, faces).expect("valid layout"));
    report("face_normals", (wall, processor));
    let (wall, processor, _) = best(repeat, || {
        layout_readout(&now, None, faces, &edges).expect("valid layout")
    });
    report("layout_readout, no rest", (wall, processor));
    assert_eq!(readout.flipped, flipped);
    println!(
        "flipped faces: {} (folded on purpose: {})",
        flipped.iter().filter(|&&flip| flip).count(),
        sizes.len().div_ceil(2000)
    );
}
