//! Kernel-only throughput of the target-mesh build and the queries, on a bumpy sphere of about
//! 1M triangles (`cargo bench -p springwrap-kernel`; `-- --triangles N` to resize).
//!
//! Query points sit a little off the surface, in mesh-vertex order ("coherent") and shuffled
//! ("random"). Not a test: it prints a table (or, with `--only`, one figure). `make bench` runs the full comparison with Blender.

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

fn read_data(path: &str) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<Vec3>) {
    let bytes = std::fs::read(path).expect("readable --data file");
    let word =
        |index: usize| u32::from_le_bytes(bytes[index * 4..index * 4 + 4].try_into().unwrap());
    let count = |index: usize| {
        u64::from_le_bytes(bytes[index * 8..index * 8 + 8].try_into().unwrap()) as usize
    };
    let (vertex_count, triangle_count, query_count) = (count(0), count(1), count(2));
    let points = |start: usize, count: usize| -> Vec<Vec3> {
        (0..count)
            .map(|index| {
                let base = start + index * 3;
                Vec3::new(
                    f32::from_bits(word(base)),
                    f32::from_bits(word(base + 1)),
                    f32::from_bits(word(base + 2)),
                )
            })
            .collect()
    };
    let vertices = points(6, vertex_count);
    let triangle_start = 6 + vertex_count * 3;
    let triangles = (0..triangle_count)
        .map(|index| {
            let base = triangle_start + index * 3;
            [word(base), word(base + 1), word(base + 2)]
        })
        .collect();
    let queries = points(triangle_start + triangle_count * 3, query_count);
    (vertices, triangles, queries)
}

fn rate(count: usize, seconds: f64) -> String {
    format!("{:>8.0}k/s", count as f64 / seconds / 1e3)
}

fn argument<T: std::str::FromStr>(arguments: &[String], name: &str) -> Option<T> {
    arguments
        .iter()
        .position(|argument| argument == name)
        .and_then(|index| arguments.get(index + 1))
        .and_then(|value| value.parse().ok())
}

/// The best of `repeat` timed runs of `run`, in seconds.
fn best_of<T>(repeat: usize, mut run: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let start = Instant::now();
        let result = run();
        best = best.min(start.elapsed().as_secs_f64());
        last = Some(result);
    }
    (best, last.unwrap())
}

fn main() {
    let arguments: Vec<String> = std::env::args().collect();
    let triangles_wanted: f64 = argument(&arguments, "--triangles").unwrap_or(1_000_000.0);
    // `--only closest|near|vertex|build` times that query alone, `--repeat` times (the best is
    // printed): one process per figure, for whole-process comparisons of two builds.
    let only: Option<String> = argument(&arguments, "--only");
    let repeat: usize = argument(&arguments, "--repeat").unwrap_or(1);
    let mut rng = Rng(42);
    // `--data FILE`: a mesh and query points from a file (three little-endian u64 counts, then
    // f32 vertex xyz, u32 triangle corners, f32 query xyz), such as the snap benchmark's torus.
    let (vertices, triangles, queries, edge) = match argument::<String>(&arguments, "--data") {
        Some(path) => {
            let (vertices, triangles, queries) = read_data(&path);
            let area: f32 = triangles
                .iter()
                .map(|[a, b, c]| {
                    let (a, b, c) = (
                        vertices[*a as usize],
                        vertices[*b as usize],
                        vertices[*c as usize],
                    );
                    (b - a).cross(c - a).length() * 0.5
                })
                .sum();
            let edge = (2.0 * area / triangles.len() as f32).sqrt();
            (vertices, triangles, queries, edge)
        }
        None => {
            let n = (triangles_wanted / 12.0).sqrt().round() as u32;
            let (vertices, triangles) = bumpy_sphere(n, &mut rng);
            let edge = 2.0 / n as f32;
            let queries: Vec<Vec3> = vertices
                .iter()
                .map(|v| *v + Vec3::new(rng.signed(), rng.signed(), rng.signed()) * edge)
                .collect();
            (vertices, triangles, queries, edge)
        }
    };
    // `--points N`: only the first N query points.
    let mut queries = queries;
    if let Some(count) = argument::<usize>(&arguments, "--points") {
        queries.truncate(count);
    }
    let mut shuffled = queries.clone();
    for index in (1..shuffled.len()).rev() {
        shuffled.swap(index, (rng.next() % (index as u64 + 1)) as usize);
    }
    // The wrap solver's pattern: each point moved a little since its last answer, which is the
    // warm start of its next query.
    let moved: Vec<Vec3> = queries
        .iter()
        .map(|q| *q + Vec3::new(rng.signed(), rng.signed(), rng.signed()) * (0.2 * edge))
        .collect();
    let triangle_count = triangles.len();
    if only.as_deref() == Some("anatomy") {
        anatomy(vertices, triangles, &queries);
        return;
    }
    let start = Instant::now();
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let build = start.elapsed().as_secs_f64();
    if let Some(only) = only {
        let (seconds, found) = match only.as_str() {
            "build" | "build-snap" => {
                // `build-snap`: the build and one closest-point query, which builds the
                // closest-point tree on first use.
                let vertices = mesh.vertices().to_vec();
                let triangles = mesh.triangles().to_vec();
                best_of(repeat, || {
                    let mesh = TargetMesh::new(
                        vertices.clone(),
                        triangles.clone(),
                        TargetMeshOptions::default(),
                    )
                    .unwrap();
                    if only == "build-snap" {
                        mesh.closest_point(Vec3::ZERO, f32::INFINITY).unwrap();
                    }
                    mesh.triangles().len()
                })
            }
            "closest" | "closest-random" => {
                let points = if only == "closest" {
                    &queries
                } else {
                    &shuffled
                };
                best_of(repeat, || {
                    mesh.closest_points(points, f32::INFINITY)
                        .unwrap()
                        .iter()
                        .flatten()
                        .count()
                })
            }
            "self-near" => {
                let near: Vec<u32> = mesh
                    .closest_points(&queries, f32::INFINITY)
                    .unwrap()
                    .iter()
                    .map(|hit| hit.unwrap().face_point.triangle)
                    .collect();
                best_of(repeat, || {
                    mesh.closest_points_near(&queries, f32::INFINITY, &near)
                        .unwrap()
                        .iter()
                        .flatten()
                        .count()
                })
            }
            "no-near" => {
                let near = vec![u32::MAX; queries.len()];
                best_of(repeat, || {
                    mesh.closest_points_near(&queries, f32::INFINITY, &near)
                        .unwrap()
                        .iter()
                        .flatten()
                        .count()
                })
            }
            "near" => {
                let near: Vec<u32> = mesh
                    .closest_points(&queries, f32::INFINITY)
                    .unwrap()
                    .iter()
                    .map(|hit| hit.unwrap().face_point.triangle)
                    .collect();
                best_of(repeat, || {
                    mesh.closest_points_near(&moved, 3.0 * edge, &near)
                        .unwrap()
                        .iter()
                        .flatten()
                        .count()
                })
            }
            "vertex" | "vertex-random" => {
                let points = if only == "vertex" {
                    &queries
                } else {
                    &shuffled
                };
                mesh.prepare_all();
                best_of(repeat, || {
                    mesh.nearest_vertices(points, f32::INFINITY)
                        .unwrap()
                        .iter()
                        .flatten()
                        .count()
                })
            }
            other => panic!("unknown --only {other}"),
        };
        println!(
            "{only}: {seconds:.4} s (best of {repeat}), {found} found, {}",
            rate(queries.len(), seconds)
        );
        return;
    }
    let start = Instant::now();
    mesh.prepare_all();
    let prepare = start.elapsed().as_secs_f64();
    // (prepare_all also builds the closest-point tree.)
    println!(
        "{triangle_count} triangles, {} queries, {} threads",
        queries.len(),
        rayon::current_num_threads()
    );
    println!(
        "build (face tree) {build:.3} s; closest-point tree + vertex tree + topology + normals {prepare:.3} s"
    );
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

/// A value from `/proc/self/status` (`VmRSS`, `VmHWM`), in bytes.
fn status_bytes(name: &str) -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|line| line.strip_prefix(name)?.strip_prefix(':'))
        .and_then(|rest| rest.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |kilobytes| kilobytes * 1024.0)
}

/// The processor time of the process over all its threads, in seconds.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or(vec![], |(_, rest)| rest.split_whitespace().collect());
    let ticks = |index: usize| fields.get(index).and_then(|f| f.parse::<f64>().ok());
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after the name.
    ticks(11)
        .zip(ticks(12))
        .map_or(f64::NAN, |(u, s)| (u + s) / 100.0)
}

/// `--only anatomy`: each part of the build timed alone, in `prepare_all`'s order (processor
/// seconds per million triangles), the peak resident set over the whole build, the bytes each structure keeps, and
/// the closest-point query rate. For the peak, run with `MALLOC_MMAP_THRESHOLD_=131072` so that
/// freed buffers leave the resident set.
fn anatomy(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>, queries: &[Vec3]) {
    let count = triangles.len() as f64;
    let per_million = |seconds: f64| seconds / count * 1e6;
    let before = status_bytes("VmRSS");
    // Resets the peak resident set to the current one.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    let mut phases = Vec::new();
    let mut timed = |name: &'static str, run: &mut dyn FnMut()| {
        let (wall, cpu) = (Instant::now(), cpu_seconds());
        run();
        phases.push((name, cpu_seconds() - cpu, wall.elapsed().as_secs_f64()));
    };
    let mut mesh = None;
    timed("TargetMesh::new", &mut || {
        mesh = Some(
            TargetMesh::new(
                vertices.clone(),
                triangles.clone(),
                TargetMeshOptions::default(),
            )
            .unwrap(),
        );
    });
    let mesh = mesh.unwrap();
    drop((vertices, triangles));
    timed("vertex tree", &mut || {
        mesh.nearest_vertices(&[Vec3::ZERO], f32::INFINITY).unwrap();
    });
    timed("topology", &mut || {
        let _ = mesh.triangle_neighbors();
    });
    timed("normals", &mut || {
        let _ = mesh.vertex_normals();
    });
    timed("closest-point tree", &mut || {
        let _ = mesh.closest_point(Vec3::ZERO, f32::INFINITY);
    });
    let peak = status_bytes("VmHWM") - before;
    let kept = status_bytes("VmRSS") - before;
    for (name, cpu, wall) in &phases {
        println!(
            "{name:>20}: {:.3} s/M triangles processor time ({:.3} s/M wall)",
            per_million(*cpu),
            per_million(*wall)
        );
    }
    let total: f64 = phases.iter().map(|(_, cpu, _)| cpu).sum();
    println!(
        "{:>20}: {:.3} s/M triangles processor time",
        "all",
        per_million(total)
    );
    let mut held = 0;
    for (name, bytes) in mesh.memory_bytes() {
        held += bytes;
        println!("{name:>20}: {:>6.1} B/triangle", bytes as f64 / count);
    }
    println!("{:>20}: {:>6.1} B/triangle", "held", held as f64 / count);
    println!(
        "peak {:.0} B/triangle over the build (inputs copied included), resident after {:.0}",
        peak / count,
        kept / count
    );
    // Query rates in processor time (over all threads), summed over enough repeats to be steady
    // on a busy machine.
    let repeat = (2_000_000 / queries.len().max(1)).clamp(1, 200);
    let per_query = |run: &dyn Fn() -> usize| {
        let start = cpu_seconds();
        for _ in 0..repeat {
            std::hint::black_box(run());
        }
        (cpu_seconds() - start) / (repeat * queries.len()) as f64
    };
    let near: Vec<u32> = mesh
        .closest_points(queries, f32::INFINITY)
        .unwrap()
        .iter()
        .map(|hit| hit.unwrap().face_point.triangle)
        .collect();
    let directions: Vec<Vec3> = queries.iter().map(|p| -*p).collect();
    let rates = [
        (
            "closest points",
            per_query(&|| mesh.closest_points(queries, f32::INFINITY).unwrap().len()),
        ),
        (
            "closest points, warm-started",
            per_query(&|| {
                mesh.closest_points_near(queries, f32::INFINITY, &near)
                    .unwrap()
                    .len()
            }),
        ),
        (
            "ray casts (both ways)",
            per_query(&|| {
                mesh.ray_casts(queries, &directions, f32::INFINITY, true)
                    .unwrap()
                    .len()
            }),
        ),
    ];
    for (name, seconds) in rates {
        println!("{name:>30}: {:.0}k/processor-second", 1e-3 / seconds);
    }
}
