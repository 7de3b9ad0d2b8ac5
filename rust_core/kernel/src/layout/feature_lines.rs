//! The layout's feature lines: chains of edges that should land on features of the target.
//!
//! Three sources, each chained on its own: edges the artist **marked** (sharp or seam edges, a
//! vertex group, an edge attribute: the caller turns them into vertex pairs), **creases** of the
//! layout's rest shape (edges between two faces whose normals differ by more than the crease
//! angle) and open **borders** (edges of one face: the rim of a hole such as a mouth or an eye).
//! A marked edge is only a marked edge, even where it is also a crease or a border.
//!
//! Chaining: a chain goes on through a vertex where two edges of its source meet, and straight on
//! through one where four meet (two lines crossing, as in a quad mesh: the edge most opposite the
//! one it came by); it stops at any other junction. A marked chain that comes back to a vertex it
//! already passed (other than closing into a loop) crosses itself: that is refused, since it
//! cannot follow one curve. A detected chain is cut there instead.
//!
//! Each line gets a kind for pairing with the target's feature curves: a border is a `Border`; a
//! crease or a marked line is a `Ridge` (convex: the faces fold away from their normals) or a
//! `Valley` (concave) by the sign of its mean dihedral angle, and a marked line whose faces bend
//! less than [`FLAT_MARKED_DEGREES`] on average is `Any` kind (a loop across a smooth region).

use std::collections::HashMap;

use glam::Vec3;

use crate::error::KernelError;
use crate::validate::{self, SettingRange, check_setting};

/// A marked line whose mean signed dihedral angle is below this (degrees) has no kind of its own.
pub const FLAT_MARKED_DEGREES: f32 = 10.0;

/// The default crease angle (degrees between the normals of two faces).
pub const DEFAULT_CREASE_DEGREES: f32 = 30.0;

/// Which features of the target a line may pair with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LineKind {
    /// A convex crease: pairs with ridges.
    Ridge,
    /// A concave crease: pairs with valleys.
    Valley,
    /// An open border: pairs with the borders of the target's holes.
    Border,
    /// A marked line across a smooth region: pairs with any curve.
    Any,
}

/// Where a line came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LineSource {
    /// Edges the caller marked.
    Marked,
    /// Edges whose dihedral angle exceeds the crease angle.
    Crease,
    /// Edges of one face.
    Border,
}

/// A chain of layout edges that is a feature.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureLine {
    /// The vertices in order; a closed line does not repeat its first vertex.
    pub vertices: Vec<u32>,
    /// Whether the last vertex connects back to the first.
    pub closed: bool,
    /// What it may pair with.
    pub kind: LineKind,
    /// Where it came from.
    pub source: LineSource,
    /// Mean signed dihedral angle of its edges between two faces, degrees (convex positive; 0 for
    /// a border).
    pub dihedral: f32,
}

/// Settings of [`feature_lines`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSettings {
    /// Edges whose face normals differ by more than this many degrees are creases; 0: no crease
    /// detection.
    pub crease_degrees: f32,
    /// Whether open borders are lines.
    pub borders: bool,
    /// Detected lines (creases, borders) with fewer edges than this are dropped; a marked line is
    /// kept from one edge on.
    pub min_edges: usize,
}

impl Default for LineSettings {
    fn default() -> Self {
        Self {
            crease_degrees: DEFAULT_CREASE_DEGREES,
            borders: true,
            min_edges: 2,
        }
    }
}

/// An undirected edge: its two vertices, the smaller first.
type Edge = (u32, u32);

/// Key of an undirected edge.
fn edge_key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Newell normal (unit, or zero for a degenerate face) and centroid of a polygon.
fn face_frame(positions: &[Vec3], corners: &[u32]) -> (Vec3, Vec3) {
    let mut normal = Vec3::ZERO;
    let mut centroid = Vec3::ZERO;
    for (index, &corner) in corners.iter().enumerate() {
        let here = positions[corner as usize];
        let next = positions[corners[(index + 1) % corners.len()] as usize];
        normal += here.cross(next);
        centroid += here;
    }
    (
        normal.normalize_or_zero(),
        centroid / corners.len().max(1) as f32,
    )
}

/// Signed dihedral angle (degrees, convex positive) across each edge used by exactly two faces,
/// and the edges used by one face.
fn edge_angles(
    positions: &[Vec3],
    face_corners: &[u32],
    face_sizes: &[u32],
) -> (HashMap<Edge, f32>, Vec<Edge>) {
    let mut faces_of: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    let mut frames = Vec::with_capacity(face_sizes.len());
    let mut start = 0usize;
    for (face, &size) in face_sizes.iter().enumerate() {
        let corners = &face_corners[start..start + size as usize];
        frames.push(face_frame(positions, corners));
        for (index, &corner) in corners.iter().enumerate() {
            let next = corners[(index + 1) % corners.len()];
            faces_of
                .entry(edge_key(corner, next))
                .or_default()
                .push(face);
        }
        start += size as usize;
    }
    let mut angles = HashMap::new();
    let mut borders = Vec::new();
    for (edge, faces) in faces_of {
        match faces.as_slice() {
            [only] if frames[*only].0 != Vec3::ZERO => borders.push(edge),
            [first, second] => {
                let (normal_a, centre_a) = frames[*first];
                let (normal_b, centre_b) = frames[*second];
                if normal_a == Vec3::ZERO || normal_b == Vec3::ZERO {
                    continue;
                }
                let angle = normal_a.dot(normal_b).clamp(-1.0, 1.0).acos().to_degrees();
                let convex = (centre_b - centre_a).dot(normal_a) <= 0.0;
                angles.insert(edge, if convex { angle } else { -angle });
            }
            _ => {}
        }
    }
    borders.sort_unstable();
    (angles, borders)
}

/// Chains of the undirected `edges` (see the module docs). `Err(vertex)` when `strict` and a
/// chain crosses itself at `vertex`.
fn chain_edges(
    positions: &[Vec3],
    edges: &[(u32, u32)],
    strict: bool,
) -> Result<Vec<(Vec<u32>, bool)>, u32> {
    let mut around: HashMap<u32, Vec<u32>> = HashMap::new();
    for &(a, b) in edges {
        around.entry(a).or_default().push(b);
        around.entry(b).or_default().push(a);
    }
    for neighbours in around.values_mut() {
        neighbours.sort_unstable();
        neighbours.dedup();
    }
    // The edge a chain arriving at `vertex` from `previous` goes on by, if any.
    let onward = |previous: u32, vertex: u32| -> Option<u32> {
        let neighbours = &around[&vertex];
        match neighbours.len() {
            2 => neighbours.iter().copied().find(|&n| n != previous),
            4 => {
                let incoming =
                    (positions[vertex as usize] - positions[previous as usize]).normalize_or_zero();
                neighbours
                    .iter()
                    .copied()
                    .filter(|&n| n != previous)
                    .max_by(|&a, &b| {
                        let along = |n: u32| {
                            (positions[n as usize] - positions[vertex as usize])
                                .normalize_or_zero()
                                .dot(incoming)
                        };
                        along(a).total_cmp(&along(b))
                    })
            }
            _ => None,
        }
    };
    let mut used: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    let mut chains = Vec::new();
    let mut sorted: Vec<(u32, u32)> = edges.iter().map(|&(a, b)| edge_key(a, b)).collect();
    sorted.sort_unstable();
    sorted.dedup();
    for &(a, b) in &sorted {
        if used.contains(&(a, b)) {
            continue;
        }
        used.insert((a, b));
        let mut chain = vec![a, b];
        let mut closed = false;
        // Walk forward from b, then backward from a (the chain reversed).
        for direction in 0..2 {
            loop {
                let (previous, vertex) = (chain[chain.len() - 2], chain[chain.len() - 1]);
                let Some(next) = onward(previous, vertex) else {
                    break;
                };
                let key = edge_key(vertex, next);
                if used.contains(&key) {
                    break;
                }
                if next == chain[0] && onward(vertex, next) == Some(chain[1]) {
                    used.insert(key);
                    closed = true;
                    break;
                }
                if chain.contains(&next) {
                    if strict {
                        return Err(next);
                    }
                    break;
                }
                used.insert(key);
                chain.push(next);
            }
            if closed {
                break;
            }
            if direction == 0 {
                chain.reverse();
            }
        }
        if !closed {
            chain.reverse();
        }
        chains.push((chain, closed));
    }
    Ok(chains)
}

/// The feature lines of a layout at `positions` with polygon faces (`face_corners`, face after
/// face, `face_sizes` corners each) and the `marked` edges (vertex pairs).
///
/// # Errors
/// [`KernelError::LayoutIndexOutOfRange`] for a face or marked edge naming a vertex the layout
/// does not have; [`KernelError::InvalidArgument`] for a face of fewer than three corners, face
/// sizes that do not add up to the corners, a marked edge from a vertex to itself, a marked line
/// that crosses itself, or a crease angle outside 0 to 180 degrees; the coordinate errors of
/// [`validate::check_coordinates`].
pub fn feature_lines(
    positions: &[Vec3],
    face_corners: &[u32],
    face_sizes: &[u32],
    marked: &[[u32; 2]],
    settings: &LineSettings,
) -> Result<Vec<FeatureLine>, KernelError> {
    validate::check_coordinates("vertex", positions)?;
    check_setting(
        "crease_degrees",
        "crease angle",
        settings.crease_degrees,
        SettingRange::closed(0.0, 180.0),
    )?;
    let vertex_count = positions.len();
    let out_of_range = |element, index, vertex| KernelError::LayoutIndexOutOfRange {
        element,
        index,
        vertex,
        vertex_count,
    };
    let corner_total: usize = face_sizes.iter().map(|&size| size as usize).sum();
    if corner_total != face_corners.len() {
        return Err(KernelError::InvalidArgument {
            name: "face sizes",
            reason: format!(
                "they add up to {corner_total} corners, the faces have {}",
                face_corners.len()
            ),
        });
    }
    let mut start = 0usize;
    for (face, &size) in face_sizes.iter().enumerate() {
        if size < 3 {
            return Err(KernelError::InvalidArgument {
                name: "face sizes",
                reason: format!("face {face} has {size} corners, a face needs at least 3"),
            });
        }
        for &corner in &face_corners[start..start + size as usize] {
            if corner as usize >= vertex_count {
                return Err(out_of_range("face", face, corner));
            }
        }
        start += size as usize;
    }
    for (index, &[a, b]) in marked.iter().enumerate() {
        for vertex in [a, b] {
            if vertex as usize >= vertex_count {
                return Err(out_of_range("marked edge", index, vertex));
            }
        }
        if a == b {
            return Err(KernelError::InvalidArgument {
                name: "marked edges",
                reason: format!("marked edge {index} joins vertex {a} to itself"),
            });
        }
    }
    let (angles, border_edges) = edge_angles(positions, face_corners, face_sizes);
    let marked_keys: Vec<(u32, u32)> = marked.iter().map(|&[a, b]| edge_key(a, b)).collect();
    let is_marked: std::collections::HashSet<(u32, u32)> = marked_keys.iter().copied().collect();
    let mut creases: Vec<(u32, u32)> = if settings.crease_degrees > 0.0 {
        angles
            .iter()
            .filter(|&(edge, angle)| {
                angle.abs() > settings.crease_degrees && !is_marked.contains(edge)
            })
            .map(|(&edge, _)| edge)
            .collect()
    } else {
        Vec::new()
    };
    creases.sort_unstable();
    let borders: Vec<(u32, u32)> = if settings.borders {
        border_edges
            .into_iter()
            .filter(|edge| !is_marked.contains(edge))
            .collect()
    } else {
        Vec::new()
    };
    let mean_angle = |chain: &[u32], closed: bool| -> Option<f32> {
        let count = if closed { chain.len() } else { chain.len() - 1 };
        let found: Vec<f32> = (0..count)
            .filter_map(|index| {
                let key = edge_key(chain[index], chain[(index + 1) % chain.len()]);
                angles.get(&key).copied()
            })
            .collect();
        (!found.is_empty()).then(|| found.iter().sum::<f32>() / found.len() as f32)
    };
    let mut lines = Vec::new();
    let sources = [
        (LineSource::Marked, marked_keys),
        (LineSource::Crease, creases),
        (LineSource::Border, borders),
    ];
    for (source, edges) in sources {
        let strict = source == LineSource::Marked;
        let chains = chain_edges(positions, &edges, strict).map_err(|vertex| {
            KernelError::InvalidArgument {
                name: "marked edges",
                reason: format!(
                    "a marked line crosses itself at vertex {vertex}: it cannot follow one curve \
                     (unmark the edges of one of its crossings)"
                ),
            }
        })?;
        for (vertices, closed) in chains {
            let edge_count = if closed {
                vertices.len()
            } else {
                vertices.len() - 1
            };
            if source != LineSource::Marked && edge_count < settings.min_edges {
                continue;
            }
            let dihedral = mean_angle(&vertices, closed);
            let kind = match (source, dihedral) {
                (LineSource::Border, _) => LineKind::Border,
                (LineSource::Marked, None) => LineKind::Border,
                (LineSource::Marked, Some(angle)) if angle.abs() < FLAT_MARKED_DEGREES => {
                    LineKind::Any
                }
                (_, Some(angle)) if angle < 0.0 => LineKind::Valley,
                _ => LineKind::Ridge,
            };
            lines.push(FeatureLine {
                vertices,
                closed,
                kind,
                source,
                dihedral: dihedral.unwrap_or(0.0),
            });
        }
    }
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An `n` × `n` grid of quads in the XY plane, its vertices row after row, folded up about
    /// `x = fold` by `degrees` (the part beyond the fold rises).
    fn grid(n: u32, fold: f32, degrees: f32) -> (Vec<Vec3>, Vec<u32>, Vec<u32>) {
        let slope = degrees.to_radians().tan();
        let positions = (0..=n)
            .flat_map(|row| {
                (0..=n).map(move |column| {
                    let x = column as f32;
                    Vec3::new(x, row as f32, (x - fold).max(0.0) * slope)
                })
            })
            .collect();
        let mut corners = Vec::new();
        for row in 0..n {
            for column in 0..n {
                let at = |r: u32, c: u32| r * (n + 1) + c;
                corners.extend([
                    at(row, column),
                    at(row, column + 1),
                    at(row + 1, column + 1),
                    at(row + 1, column),
                ]);
            }
        }
        let sizes = vec![4; (n * n) as usize];
        (positions, corners, sizes)
    }

    #[test]
    fn a_fold_is_one_valley_crease_and_the_rim_one_border_loop() {
        let (positions, corners, sizes) = grid(4, 2.0, 60.0);
        let lines =
            feature_lines(&positions, &corners, &sizes, &[], &LineSettings::default()).unwrap();
        let creases: Vec<_> = lines
            .iter()
            .filter(|line| line.source == LineSource::Crease)
            .collect();
        assert_eq!(creases.len(), 1);
        assert_eq!(creases[0].vertices.len(), 5);
        assert!(creases[0].vertices.iter().all(|&v| v % 5 == 2));
        // Folding up towards the normal (+Z) is concave.
        assert_eq!(creases[0].kind, LineKind::Valley);
        assert!((creases[0].dihedral + 60.0).abs() < 0.1);
        let borders: Vec<_> = lines
            .iter()
            .filter(|line| line.source == LineSource::Border)
            .collect();
        assert_eq!(borders.len(), 1);
        assert!(borders[0].closed);
        assert_eq!(borders[0].vertices.len(), 16);
        // Below the crease angle there is no crease; no borders when not asked.
        let settings = LineSettings {
            crease_degrees: 70.0,
            borders: false,
            ..LineSettings::default()
        };
        assert!(
            feature_lines(&positions, &corners, &sizes, &[], &settings)
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn marked_lines_go_straight_through_crossings_and_take_precedence() {
        let (positions, corners, sizes) = grid(4, 2.0, 60.0);
        // Column 2 (the crease) and row 2 marked: two lines crossing at vertex 12.
        let mut marked: Vec<[u32; 2]> = (0..4).map(|r| [r * 5 + 2, (r + 1) * 5 + 2]).collect();
        marked.extend((0..4).map(|c| [10 + c, 10 + c + 1]));
        let settings = LineSettings {
            borders: false,
            ..LineSettings::default()
        };
        let lines = feature_lines(&positions, &corners, &sizes, &marked, &settings).unwrap();
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines.iter().all(|line| line.source == LineSource::Marked));
        assert!(lines.iter().all(|line| line.vertices.len() == 5));
        let kinds: Vec<_> = lines.iter().map(|line| line.kind).collect();
        assert!(kinds.contains(&LineKind::Valley) && kinds.contains(&LineKind::Any));
    }

    #[test]
    fn a_marked_line_crossing_itself_is_refused() {
        let (positions, corners, sizes) = grid(4, 2.0, 0.0);
        // A figure eight: the square 12-13-8-7 and the square 12-11-16-17, straight through 12.
        let eight = [12, 13, 8, 7, 12, 11, 16, 17, 12];
        let marked: Vec<[u32; 2]> = eight.windows(2).map(|pair| [pair[0], pair[1]]).collect();
        let error = feature_lines(
            &positions,
            &corners,
            &sizes,
            &marked,
            &LineSettings::default(),
        )
        .unwrap_err();
        assert!(
            error.to_string().contains("crosses itself at vertex 12"),
            "{error}"
        );
    }

    #[test]
    fn bad_marked_edges_are_refused() {
        let (positions, corners, sizes) = grid(2, 1.0, 0.0);
        let settings = LineSettings::default();
        assert!(matches!(
            feature_lines(&positions, &corners, &sizes, &[[0, 99]], &settings),
            Err(KernelError::LayoutIndexOutOfRange { vertex: 99, .. })
        ));
        assert!(
            feature_lines(&positions, &corners, &sizes, &[[3, 3]], &settings)
                .unwrap_err()
                .to_string()
                .contains("to itself")
        );
        assert!(
            feature_lines(&positions, &corners, &sizes[1..], &[], &settings)
                .unwrap_err()
                .to_string()
                .contains("add up")
        );
    }
}
