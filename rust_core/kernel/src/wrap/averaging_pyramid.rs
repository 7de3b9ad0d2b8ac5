//! Many rounds of averaging over a layout's edge neighbours at a fraction of their cost: most of
//! the rounds are done on coarser graphs of aggregates of vertices.
//!
//! A round replaces each vertex's value by the mean of its own and its neighbours'. `r` rounds
//! spread a value over a kernel whose variance grows by a fixed amount per round (about `√r`
//! rings wide). On a graph of aggregates (each a vertex and its neighbours, a level coarser
//! again of aggregates of aggregates), a round weighs each aggregate by its vertex count and each
//! pair of aggregates by the edges between them, and spreads over several rings at once. Going
//! down averages each aggregate's members, going up hands each member its aggregate's value
//! followed by a few rounds on the finer level (which smooth the aggregates' steps away). The
//! variances are measured on the rest shape, level by level, and the cheapest plan whose total
//! variance is that of the rounds asked for is chosen: 64 rounds on a grid cost about six.

use glam::{Quat, Vec3, Vec4};
use rayon::prelude::*;

use crate::cancel::{Stop, check};
use crate::error::KernelError;
use crate::layout::LayoutStructure;

/// Rounds on each finer level after going up (they smooth the aggregates' steps away).
const ROUNDS_UP: usize = 2;
/// The levels end when one has at most this many aggregates, or hardly shrinks.
const FEWEST_AGGREGATES: usize = 64;
/// Going down and up may take at most this share of the variance asked for (the rest rounds on
/// the coarsest level used): the aggregates' steps stay small beside the kernel. Measured on a
/// spike on a grid, 64 rounds: at a quarter the pyramid stops one level down (about six finest
/// rounds' cost), its kernel within a few percent of the exact one's peak; going a level further
/// costs less but puts the kernel off centre by a coarse aggregate.
const MAX_STEP_SHARE: f64 = 0.25;
const MAX_LEVELS: usize = 8;

/// A value that can be averaged with weights.
pub(crate) trait Averaged: Copy + Send + Sync {
    /// The mean of `self` with weight `own` and `others` with their weights.
    fn mean(self, own: f32, others: impl Iterator<Item = (Self, f32)>) -> Self;
}

impl Averaged for Quat {
    /// As quaternions, each other's sign matched to `self`'s, normalised; `self` when the sum
    /// vanishes.
    fn mean(self, own: f32, others: impl Iterator<Item = (Self, f32)>) -> Self {
        let reference = Vec4::from(self);
        let sum = others.fold(reference * own, |sum, (other, weight)| {
            let other = Vec4::from(other);
            if other.dot(reference) < 0.0 {
                sum - other * weight
            } else {
                sum + other * weight
            }
        });
        let length = sum.length();
        if length > 0.0 && length.is_finite() {
            Quat::from_vec4(sum / length)
        } else {
            self
        }
    }
}

impl Averaged for f32 {
    /// The others summed first, then `self` added (with weights 1, to the bit the plain mean of
    /// a vertex and its neighbours).
    fn mean(self, own: f32, others: impl Iterator<Item = (Self, f32)>) -> Self {
        let (sum, total) = others.fold((0.0, 0.0), |(sum, total), (other, weight)| {
            (sum + other * weight, total + weight)
        });
        (self * own + sum) / (own + total)
    }
}

/// A graph of aggregates: per aggregate its vertex count, its neighbours and the edges to each.
#[derive(Debug, Clone)]
struct Graph {
    masses: Vec<f32>,
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    weights: Vec<f32>,
}

impl Graph {
    fn len(&self) -> usize {
        self.masses.len()
    }

    fn edges(&self, node: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        let range = self.offsets[node] as usize..self.offsets[node + 1] as usize;
        self.neighbours[range.clone()]
            .iter()
            .map(|&other| other as usize)
            .zip(self.weights[range].iter().copied())
    }

    /// The rest-shape variance one round adds (a mean over the mass), given each node's centroid.
    fn round_variance(&self, centroids: &[Vec3]) -> f64 {
        let total: f64 = (0..self.len())
            .map(|node| {
                let (spread, weight) =
                    self.edges(node)
                        .fold((0.0, 0.0), |(spread, weight), (other, w)| {
                            let distance =
                                f64::from(centroids[other].distance_squared(centroids[node]));
                            (spread + f64::from(w) * distance, weight + f64::from(w))
                        });
                let mass = f64::from(self.masses[node]);
                mass * spread / (mass + weight)
            })
            .sum();
        let mass: f64 = self.masses.iter().map(|&m| f64::from(m)).sum();
        total / mass.max(f64::MIN_POSITIVE)
    }
}

/// One coarser level: how the finer level's nodes group into it, and its graph.
#[derive(Debug, Clone)]
struct Level {
    /// Per finer node, its aggregate.
    aggregate_of: Vec<u32>,
    /// The finer nodes of each aggregate.
    member_offsets: Vec<u32>,
    members: Vec<u32>,
    graph: Graph,
    /// The variance of one round here, and of going down here and back up, in finest rounds.
    round_rounds: f64,
    down_up_rounds: f64,
}

/// The coarser levels of a layout's graph, with their rounds' variances.
#[derive(Debug, Clone)]
pub(crate) struct AveragingPyramid {
    levels: Vec<Level>,
    /// The finest graph's vertex count.
    vertices: usize,
}

/// Groups the nodes of `graph`: a node whose neighbours are all free starts an aggregate with
/// them; the others join their most connected aggregated neighbour, or stand alone.
fn aggregate(graph: &Graph) -> (Vec<u32>, usize) {
    let mut aggregate_of = vec![u32::MAX; graph.len()];
    let mut count = 0u32;
    for node in 0..graph.len() {
        if aggregate_of[node] != u32::MAX
            || graph
                .edges(node)
                .any(|(other, _)| aggregate_of[other] != u32::MAX)
        {
            continue;
        }
        aggregate_of[node] = count;
        for (other, _) in graph.edges(node) {
            aggregate_of[other] = count;
        }
        count += 1;
    }
    let first = aggregate_of.clone();
    for node in 0..graph.len() {
        if first[node] != u32::MAX {
            continue;
        }
        let joined = graph
            .edges(node)
            .filter(|&(other, _)| first[other] != u32::MAX)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(other, _)| first[other]);
        aggregate_of[node] = joined.unwrap_or_else(|| {
            count += 1;
            count - 1
        });
    }
    (aggregate_of, count as usize)
}

/// The graph of the aggregates of `graph`, and the members of each.
fn coarsen(graph: &Graph, aggregate_of: &[u32], count: usize) -> (Graph, Vec<u32>, Vec<u32>) {
    let mut member_offsets = vec![0u32; count + 1];
    for &aggregate in aggregate_of {
        member_offsets[aggregate as usize + 1] += 1;
    }
    for index in 0..count {
        member_offsets[index + 1] += member_offsets[index];
    }
    let mut members = vec![0u32; aggregate_of.len()];
    let mut next = member_offsets.clone();
    for (node, &aggregate) in aggregate_of.iter().enumerate() {
        members[next[aggregate as usize] as usize] = node as u32;
        next[aggregate as usize] += 1;
    }
    let rows: Vec<(f32, Vec<(u32, f32)>)> = (0..count)
        .into_par_iter()
        .with_min_len(1024)
        .map(|aggregate| {
            let range = member_offsets[aggregate] as usize..member_offsets[aggregate + 1] as usize;
            let mut mass = 0.0;
            let mut entries: Vec<(u32, f32)> = Vec::new();
            for &member in &members[range] {
                mass += graph.masses[member as usize];
                for (other, weight) in graph.edges(member as usize) {
                    let other = aggregate_of[other];
                    if other as usize != aggregate {
                        entries.push((other, weight));
                    }
                }
            }
            entries.sort_unstable_by_key(|&(other, _)| other);
            entries.dedup_by(|later, kept| {
                let same = later.0 == kept.0;
                if same {
                    kept.1 += later.1;
                }
                same
            });
            (mass, entries)
        })
        .collect();
    let mut coarse = Graph {
        masses: Vec::with_capacity(count),
        offsets: vec![0],
        neighbours: Vec::new(),
        weights: Vec::new(),
    };
    for (mass, entries) in rows {
        coarse.masses.push(mass);
        for (other, weight) in entries {
            coarse.neighbours.push(other);
            coarse.weights.push(weight);
        }
        coarse.offsets.push(coarse.neighbours.len() as u32);
    }
    (coarse, member_offsets, members)
}

/// The mass-weighted centroid of each aggregate's members.
fn centroids(level: &Level, finer: &Graph, finer_centroids: &[Vec3]) -> Vec<Vec3> {
    (0..level.graph.len())
        .map(|aggregate| {
            let range = level.member_offsets[aggregate] as usize
                ..level.member_offsets[aggregate + 1] as usize;
            let sum = level.members[range]
                .iter()
                .map(|&member| finer_centroids[member as usize] * finer.masses[member as usize])
                .sum::<Vec3>();
            sum / level.graph.masses[aggregate]
        })
        .collect()
}

impl AveragingPyramid {
    /// The levels of `structure`'s edge graph, their variances measured on `rest`; `None` when
    /// the rest shape gives no measure (no edge of length, not finite).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] never yet (kept for out-of-memory checks).
    pub(crate) fn new(structure: &LayoutStructure, rest: &[Vec3]) -> Option<Self> {
        let vertices = structure.vertex_count;
        let mut finest = Graph {
            masses: vec![1.0; vertices],
            offsets: Vec::with_capacity(vertices + 1),
            neighbours: Vec::new(),
            weights: Vec::new(),
        };
        finest.offsets.push(0);
        for vertex in 0..vertices as u32 {
            let neighbours = structure.neighbors_of(vertex);
            finest.neighbours.extend_from_slice(neighbours);
            finest.weights.extend(neighbours.iter().map(|_| 1.0f32));
            finest.offsets.push(finest.neighbours.len() as u32);
        }
        let fine_round = finest.round_variance(rest);
        if !(fine_round > 0.0 && fine_round.is_finite()) {
            return None;
        }
        let mut levels: Vec<Level> = Vec::new();
        let mut centroids_now = rest.to_vec();
        while levels.len() < MAX_LEVELS {
            let graph = levels.last().map_or(&finest, |level| &level.graph);
            if graph.len() <= FEWEST_AGGREGATES {
                break;
            }
            let (aggregate_of, count) = aggregate(graph);
            if count * 3 > graph.len() * 2 {
                break;
            }
            let (coarse, member_offsets, members) = coarsen(graph, &aggregate_of, count);
            let mut level = Level {
                aggregate_of,
                member_offsets,
                members,
                graph: coarse,
                round_rounds: 0.0,
                down_up_rounds: 0.0,
            };
            let coarse_centroids = centroids(&level, graph, &centroids_now);
            // The spread of the members about their aggregate's centroid: averaging them going
            // down and handing the value back going up each add it.
            let spread: f64 = level
                .aggregate_of
                .iter()
                .enumerate()
                .map(|(node, &aggregate)| {
                    f64::from(graph.masses[node])
                        * f64::from(
                            centroids_now[node]
                                .distance_squared(coarse_centroids[aggregate as usize]),
                        )
                })
                .sum::<f64>()
                / vertices as f64;
            level.down_up_rounds = 2.0 * spread / fine_round;
            level.round_rounds = level.graph.round_variance(&coarse_centroids) / fine_round;
            centroids_now = coarse_centroids;
            levels.push(level);
        }
        Some(Self { levels, vertices })
    }

    /// The cheapest plan for `rounds` finest rounds: the coarsest level to go down to (0: none)
    /// and the rounds there.
    fn plan(&self, rounds: usize) -> (usize, usize) {
        let wanted = rounds as f64;
        let mut best = (0, rounds);
        let mut best_cost = wanted;
        let (mut fixed, mut fixed_cost) = (0.0, 0.0);
        let mut finer_rounds = 1.0;
        let mut finer_size = 1.0;
        for (index, level) in self.levels.iter().enumerate() {
            fixed += level.down_up_rounds + ROUNDS_UP as f64 * finer_rounds;
            fixed_cost += (2 + ROUNDS_UP) as f64 * finer_size;
            if fixed > wanted * MAX_STEP_SHARE {
                break;
            }
            let size = level.graph.len() as f64 / self.vertices as f64;
            let here = ((wanted - fixed) / level.round_rounds).round();
            let cost = fixed_cost + here * size;
            if cost < best_cost {
                best = (index + 1, here as usize);
                best_cost = cost;
            }
            finer_rounds = level.round_rounds;
            finer_size = size;
        }
        best
    }

    /// `values` (one per vertex) smoothed as `rounds` rounds of averaging over edge neighbours
    /// would, most rounds on coarser levels; `stop` is asked before each round.
    ///
    /// # Errors
    /// [`KernelError::Cancelled`] once `stop` said true.
    pub(crate) fn smooth<T: Averaged>(
        &self,
        structure: &LayoutStructure,
        values: &mut Vec<T>,
        rounds: usize,
        stop: Stop<'_>,
    ) -> Result<(), KernelError> {
        let (depth, coarse_rounds) = self.plan(rounds);
        if depth == 0 {
            return fine_rounds(structure, values, rounds, stop);
        }
        // Down: each aggregate the mean of its members (weighed by their vertex counts).
        let mut stack: Vec<Vec<T>> = Vec::with_capacity(depth);
        let mut current = std::mem::take(values);
        let mut finer_masses: Option<&[f32]> = None;
        for level in &self.levels[..depth] {
            check(stop, super::linear_system::WRAP_STEP)?;
            let down: Vec<T> = (0..level.graph.len())
                .into_par_iter()
                .with_min_len(1024)
                .map(|aggregate| {
                    let range = level.member_offsets[aggregate] as usize
                        ..level.member_offsets[aggregate + 1] as usize;
                    let members = &level.members[range];
                    let mass = |member: u32| finer_masses.map_or(1.0, |m| m[member as usize]);
                    let first = members[0];
                    current[first as usize].mean(
                        mass(first),
                        members[1..]
                            .iter()
                            .map(|&member| (current[member as usize], mass(member))),
                    )
                })
                .collect();
            stack.push(current);
            current = down;
            finer_masses = Some(&level.graph.masses);
        }
        for _ in 0..coarse_rounds {
            check(stop, super::linear_system::WRAP_STEP)?;
            current = graph_round(&self.levels[depth - 1].graph, &current);
        }
        // Up: each member its aggregate's value, then a few rounds on its level.
        for index in (0..depth).rev() {
            let level = &self.levels[index];
            let mut finer = stack.pop().expect("one per level");
            finer
                .par_iter_mut()
                .with_min_len(4096)
                .zip(&level.aggregate_of)
                .for_each(|(value, &aggregate)| *value = current[aggregate as usize]);
            current = finer;
            if index == 0 {
                fine_rounds(structure, &mut current, ROUNDS_UP, stop)?;
            } else {
                for _ in 0..ROUNDS_UP {
                    check(stop, super::linear_system::WRAP_STEP)?;
                    current = graph_round(&self.levels[index - 1].graph, &current);
                }
            }
        }
        *values = current;
        Ok(())
    }
}

/// `values` (one per vertex) smoothed by `rounds` rounds of averaging over edge neighbours: through
/// `pyramid` when there is one (a layout too large to factor), else round by round.
///
/// # Errors
/// [`KernelError::Cancelled`] once `stop` said true.
pub(crate) fn smooth_over<T: Averaged>(
    pyramid: Option<&AveragingPyramid>,
    structure: &LayoutStructure,
    values: &mut Vec<T>,
    rounds: usize,
    stop: Stop<'_>,
) -> Result<(), KernelError> {
    match pyramid {
        Some(pyramid) => pyramid.smooth(structure, values, rounds, stop),
        None => fine_rounds(structure, values, rounds, stop),
    }
}

/// One round on a graph of aggregates.
fn graph_round<T: Averaged>(graph: &Graph, values: &[T]) -> Vec<T> {
    (0..graph.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|node| {
            values[node].mean(
                graph.masses[node],
                graph
                    .edges(node)
                    .map(|(other, weight)| (values[other], weight)),
            )
        })
        .collect()
}

/// `rounds` rounds of averaging each vertex with its edge neighbours (each weighing as much); two
/// buffers, each round written into the other (a round's fresh vector of a million rotations
/// cost more in page faults than its arithmetic).
///
/// # Errors
/// [`KernelError::Cancelled`] once `stop` said true.
pub(crate) fn fine_rounds<T: Averaged>(
    structure: &LayoutStructure,
    values: &mut Vec<T>,
    rounds: usize,
    stop: Stop<'_>,
) -> Result<(), KernelError> {
    if rounds == 0 {
        return Ok(());
    }
    // Two buffers, each round written into the other.
    let mut smoothed = values.clone();
    for _ in 0..rounds {
        check(stop, super::linear_system::WRAP_STEP)?;
        smoothed
            .par_iter_mut()
            .with_min_len(2048)
            .enumerate()
            .for_each(|(vertex, smoothed)| {
                let neighbours = structure.neighbors_of(vertex as u32);
                *smoothed = values[vertex].mean(
                    1.0,
                    neighbours
                        .iter()
                        .map(|&other| (values[other as usize], 1.0)),
                );
            });
        std::mem::swap(values, &mut smoothed);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::NEVER;

    /// A `side` x `side` quad grid of unit cells.
    fn grid(side: u32) -> (LayoutStructure, Vec<Vec3>) {
        let mut corners = Vec::new();
        for y in 0..side - 1 {
            for x in 0..side - 1 {
                let a = y * side + x;
                corners.extend([a, a + 1, a + side + 1, a + side]);
            }
        }
        let faces = vec![4; ((side - 1) * (side - 1)) as usize];
        let structure =
            LayoutStructure::new((side * side) as usize, &corners, &faces, &[], &[]).unwrap();
        let rest = (0..side * side)
            .map(|index| Vec3::new((index % side) as f32, (index / side) as f32, 0.0))
            .collect();
        (structure, rest)
    }

    /// The second moment of `values` about `(x, y)` over the sum of `values`.
    fn spread(values: &[f32], side: u32, x: u32, y: u32) -> (f64, f64) {
        let total: f64 = values.iter().map(|&v| f64::from(v)).sum();
        let moment: f64 = values
            .iter()
            .enumerate()
            .map(|(index, &v)| {
                let dx = f64::from(index as u32 % side) - f64::from(x);
                let dy = f64::from(index as u32 / side) - f64::from(y);
                f64::from(v) * (dx * dx + dy * dy)
            })
            .sum();
        (moment / total, total)
    }

    #[test]
    fn sixty_four_rounds_through_the_pyramid_spread_a_spike_as_far_as_sixty_four_rounds() {
        let side = 121;
        let (structure, rest) = grid(side);
        let pyramid = AveragingPyramid::new(&structure, &rest).unwrap();
        let (depth, rounds) = pyramid.plan(64);
        assert!(depth >= 1 && rounds < 64, "{depth} levels, {rounds} rounds");
        let centre = 60 * side + 60;
        let mut spike = vec![0.0f32; (side * side) as usize];
        spike[centre as usize] = 1.0;
        let mut exact = spike.clone();
        fine_rounds(&structure, &mut exact, 64, NEVER).unwrap();
        let mut fast = spike.clone();
        pyramid.smooth(&structure, &mut fast, 64, NEVER).unwrap();
        let (exact_spread, _) = spread(&exact, side, 60, 60);
        let (fast_spread, _) = spread(&fast, side, 60, 60);
        assert!(
            (fast_spread / exact_spread - 1.0).abs() < 0.25,
            "{fast_spread} against {exact_spread}"
        );
        // Close to the exact kernel: the difference small beside its peak.
        let peak = exact.iter().copied().fold(0.0, f32::max);
        let difference = exact
            .iter()
            .zip(&fast)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            difference < 0.35 * peak,
            "{difference} against a peak of {peak}"
        );
    }

    #[test]
    fn few_rounds_stay_on_the_finest_level_and_rotations_stay_unit() {
        let (structure, rest) = grid(40);
        let pyramid = AveragingPyramid::new(&structure, &rest).unwrap();
        assert_eq!(pyramid.plan(2), (0, 2));
        let mut rotations: Vec<Quat> = (0..1600)
            .map(|index| {
                Quat::from_rotation_z(index as f32 * 0.01) * if index % 2 == 0 { 1.0 } else { -1.0 }
            })
            .collect();
        pyramid
            .smooth(&structure, &mut rotations, 64, NEVER)
            .unwrap();
        assert!(rotations.iter().all(|q| (q.length() - 1.0).abs() < 1e-5));
        // A constant stays.
        let mut constant = vec![2.5f32; 1600];
        pyramid
            .smooth(&structure, &mut constant, 64, NEVER)
            .unwrap();
        assert!(constant.iter().all(|v| (v - 2.5).abs() < 1e-5));
    }
}
