//! Building obvhs BVHs and the nearest-primitive traversal obvhs does not provide.
//!
//! Both trees of a [`crate::TargetMesh`] are obvhs `Bvh2`s: the face tree over triangle boxes
//! and the vertex tree over point boxes. obvhs traverses rays; closest-point search is the
//! classic best-first descent written here: visit the nearer child first and prune every
//! node whose box is farther than the best primitive found so far.

use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{
    Bvh2, leaf_collapser::collapse, node::Bvh2Node, reinsertion::ReinsertionOptimizer,
};
use obvhs::ploc::{PlocBuilder, SortPrecision};
use rayon::prelude::*;

/// Builds a binary BVH over boxes with the preset the kernel uses everywhere.
#[must_use]
pub fn build_bvh(boxes: &[Aabb]) -> Bvh2 {
    build_bvh_with(boxes.len(), |index| boxes[index])
}

/// Builds a binary BVH over `count` primitives whose boxes `bounds(index)` gives, without a
/// list of the boxes (32 bytes per primitive more at the build's peak).
///
/// obvhs's PLOC with a search radius of 2 (1 for the first two levels) and reinsertion of 1% of
/// the nodes, then leaves of at most 4 primitives (one SIMD packet of the closest-point tree).
/// Measured on 2M triangles (`cargo bench -p springwrap-kernel -- --only anatomy`): 20% less
/// processor time than obvhs's `fast_build` (radius 6, 2% reinsertion) and closest-point and
/// ray queries as fast. The nodes are not reordered for traversal (closest-point queries use
/// the four-wide tree built from this one, rays were as fast without) and the parent links the
/// optimiser needs are dropped after it.
#[must_use]
pub fn build_bvh_with(count: usize, bounds: impl Fn(usize) -> Aabb + Sync) -> Bvh2 {
    let mut bvh = Bvh2::zeroed(count);
    if count == 0 {
        return bvh;
    }
    bvh.primitive_indices
        .par_iter_mut()
        .enumerate()
        .for_each(|(index, slot)| *slot = index as u32);
    let mut builder = PlocBuilder::new();
    builder.current_nodes = (0..count)
        .into_par_iter()
        .with_min_len(4096)
        .map(|index| Bvh2Node::new(bounds(index), 1, index as u32))
        .collect();
    let total = builder
        .current_nodes
        .par_iter()
        .with_min_len(4096)
        .fold(Aabb::empty, |total, node| total.union(node.aabb()))
        .reduce(Aabb::empty, |a, b| a.union(&b));
    builder.build_ploc_from_leaves::<2, false>(&mut bvh, total, SortPrecision::U64, 2);
    drop(builder);
    ReinsertionOptimizer::default().run(&mut bvh, 0.01, None);
    collapse(&mut bvh, 4, 3.0);
    bvh.parents = Vec::new();
    bvh.primitives_to_nodes = Vec::new();
    bvh.nodes.shrink_to_fit();
    bvh.primitive_indices.shrink_to_fit();
    bvh
}

/// Squared distance from `point` to the box (zero inside).
#[must_use]
#[inline(always)]
pub fn box_distance_squared(aabb: &Aabb, point: Vec3A) -> f32 {
    let outside = (aabb.min - point).max(point - aabb.max).max(Vec3A::ZERO);
    outside.length_squared()
}

/// A four-wide BVH for nearest-primitive queries, collapsed from a [`Bvh2`].
///
/// Each node holds the boxes of up to four children as six arrays of four (structure of
/// arrays), so that one node visit measures the distance to all four boxes at once with SIMD
/// (`glam::Vec4`). A child is an inner node or a leaf: a range of BVH slots (the same slots as
/// the `Bvh2`'s `primitive_indices`, so primitive data kept in slot order stays valid).
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    /// The nodes; the root is `nodes[0]`, every child comes after its parent.
    pub nodes: Vec<Bvh4Node>,
}

/// One node of a [`Bvh4`]: four child boxes and what each child is.
///
/// A child with `counts[i] == 0` is the inner node `nodes[children[i]]`; with `counts[i] > 0` it
/// is a leaf of the slots `children[i] .. children[i] + counts[i]`. Unused children have an
/// empty box (min `+inf`, max `-inf`: infinitely far from every point).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Bvh4Node {
    /// Box minimum x of each child.
    pub min_x: [f32; 4],
    /// Box minimum y of each child.
    pub min_y: [f32; 4],
    /// Box minimum z of each child.
    pub min_z: [f32; 4],
    /// Box maximum x of each child.
    pub max_x: [f32; 4],
    /// Box maximum y of each child.
    pub max_y: [f32; 4],
    /// Box maximum z of each child.
    pub max_z: [f32; 4],
    /// Inner node index, or first slot of a leaf.
    pub children: [u32; 4],
    /// Slot count of a leaf child, 0 for an inner node (or an unused child).
    pub counts: [u16; 4],
    /// Bit `i` set when child `i` is a leaf.
    pub leaf_mask: u32,
}

impl Bvh4Node {
    const EMPTY: Self = Self {
        min_x: [f32::INFINITY; 4],
        min_y: [f32::INFINITY; 4],
        min_z: [f32::INFINITY; 4],
        max_x: [f32::NEG_INFINITY; 4],
        max_y: [f32::NEG_INFINITY; 4],
        max_z: [f32::NEG_INFINITY; 4],
        children: [u32::MAX; 4],
        counts: [0; 4],
        leaf_mask: 0,
    };

    fn set_leaf(&mut self, child: usize, first: u32, count: u32) {
        assert!(count > 0, "a leaf holds at least one primitive");
        self.children[child] = first;
        self.counts[child] = u16::try_from(count).expect("at most 65535 primitives a leaf");
        self.leaf_mask |= 1 << child;
    }

    fn set_box(&mut self, child: usize, aabb: &Aabb) {
        self.min_x[child] = aabb.min.x;
        self.min_y[child] = aabb.min.y;
        self.min_z[child] = aabb.min.z;
        self.max_x[child] = aabb.max.x;
        self.max_y[child] = aabb.max.y;
        self.max_z[child] = aabb.max.z;
    }

    /// Squared distances from `point` (splatted per axis) to the four child boxes, as
    /// [`box_distance_squared`] computes them (`+inf` for unused children).
    #[inline(always)]
    fn distances_squared(&self, x: Vec4, y: Vec4, z: Vec4) -> Vec4 {
        let dx = (Vec4::from_array(self.min_x) - x)
            .max(x - Vec4::from_array(self.max_x))
            .max(Vec4::ZERO);
        let dy = (Vec4::from_array(self.min_y) - y)
            .max(y - Vec4::from_array(self.max_y))
            .max(Vec4::ZERO);
        let dz = (Vec4::from_array(self.min_z) - z)
            .max(z - Vec4::from_array(self.max_z))
            .max(Vec4::ZERO);
        dx * dx + dy * dy + dz * dz
    }
}

impl Bvh4 {
    /// Collapses a binary BVH: each node takes the up-to-four descendants found by opening,
    /// again and again, its inner child with the largest surface area. An inner node whose two
    /// children are leaves of adjacent slots becomes one leaf of both (at most
    /// [`Bvh4::MAX_LEAF_SLOTS`]): a node of two leaves is 128 bytes for two packets, and the
    /// leaf's slots pack tighter into packets of four.
    ///
    /// # Panics
    /// With 2^32 nodes or more, or a leaf of more than 65535 primitives.
    #[must_use]
    pub fn from_bvh2(bvh2: &Bvh2) -> Self {
        let Some(root) = bvh2.nodes.first() else {
            return Self::default();
        };
        let mut nodes = vec![Bvh4Node::EMPTY];
        if let Some((first, count)) = leaf_slots(bvh2, 0) {
            nodes[0].set_box(0, root.aabb());
            nodes[0].set_leaf(0, first, count);
            return Self { nodes };
        }
        // (Bvh4 node to fill, the Bvh2 inner node it stands for).
        let mut pending = vec![(0u32, 0u32)];
        while let Some((target, source)) = pending.pop() {
            let first = bvh2.nodes[source as usize].first_index;
            let mut children = [first, first + 1, 0, 0];
            let mut count = 2;
            while count < 4 {
                let widest = (0..count)
                    .filter(|&child| leaf_slots(bvh2, children[child]).is_none())
                    .max_by(|&a, &b| {
                        let area =
                            |child: usize| bvh2.nodes[children[child] as usize].aabb().half_area();
                        area(a).total_cmp(&area(b))
                    });
                let Some(widest) = widest else { break };
                let opened = bvh2.nodes[children[widest] as usize].first_index;
                children[widest] = opened;
                children[count] = opened + 1;
                count += 1;
            }
            for (child, &source_child) in children[..count].iter().enumerate() {
                let node = &bvh2.nodes[source_child as usize];
                let target_node = &mut nodes[target as usize];
                target_node.set_box(child, node.aabb());
                if let Some((first, count)) = leaf_slots(bvh2, source_child) {
                    target_node.set_leaf(child, first, count);
                } else {
                    let index = u32::try_from(nodes.len()).expect("fewer than 2^32 BVH nodes");
                    nodes[target as usize].children[child] = index;
                    nodes.push(Bvh4Node::EMPTY);
                    pending.push((index, source_child));
                }
            }
        }
        Self { nodes }
    }

    /// The most slots a leaf made of two binary leaves holds.
    pub const MAX_LEAF_SLOTS: u32 = 8;
}

/// The slots `(first, count)` of `bvh2.nodes[index]` as one leaf of a [`Bvh4`]: a leaf's, or an
/// inner node's whose two children are leaves of adjacent slots, at most
/// [`Bvh4::MAX_LEAF_SLOTS`] in all; `None` for other inner nodes.
fn leaf_slots(bvh2: &Bvh2, index: u32) -> Option<(u32, u32)> {
    let node = &bvh2.nodes[index as usize];
    if node.prim_count > 0 {
        return Some((node.first_index, node.prim_count));
    }
    let left = &bvh2.nodes[node.first_index as usize];
    let right = &bvh2.nodes[node.first_index as usize + 1];
    let count = left.prim_count + right.prim_count;
    (left.prim_count > 0
        && right.prim_count > 0
        && right.first_index == left.first_index + left.prim_count
        && count <= Bvh4::MAX_LEAF_SLOTS)
        .then_some((left.first_index, count))
}

impl Bvh4 {
    /// Replaces every leaf `(first, count)` by `renumber(first, count)`, node by node in order
    /// (so that data laid out in the order of the calls follows the traversal order).
    pub fn renumber_leaves(&mut self, mut renumber: impl FnMut(u32, u32) -> (u32, u32)) {
        for node in &mut self.nodes {
            for child in 0..4 {
                if node.leaf_mask & (1 << child) != 0 {
                    let (first, count) =
                        renumber(node.children[child], u32::from(node.counts[child]));
                    node.leaf_mask &= !(1 << child);
                    node.set_leaf(child, first, count);
                }
            }
        }
    }
}

/// Reusable traversal stack of `(node, squared distance to its box)`.
pub type NearestStack = Vec<(u32, f32)>;

/// Best-first search for the primitive nearest to `point` within `max_distance_squared`.
///
/// `search_leaf(first, count, best)` searches the leaf `first .. first + count` (BVH slots, or
/// whatever the leaves were renumbered to with [`Bvh4::renumber_leaves`]) and returns its
/// primitive `(slot, squared distance)` nearest to `point` if that is strictly below `best`, the
/// best squared distance so far; [`search_slots`] turns a per-slot distance into such a search.
/// `warm_start` is an optional known candidate `(slot, squared distance)`, typically the answer
/// of the previous, nearby query: its distance bounds the search from the start, so most of the
/// tree is pruned at once. Returns the best `(slot, squared distance)` strictly below
/// `max_distance_squared`, or `None`.
///
/// Each node visit measures its four child boxes at once; leaf children are searched at once,
/// nearest first; the search goes on with the nearest inner child and pushes the others,
/// farthest first, so that the nearest is popped next.
#[inline]
pub fn nearest_slot<F: FnMut(usize, usize, f32) -> Option<(usize, f32)>>(
    bvh: &Bvh4,
    point: Vec3A,
    max_distance_squared: f32,
    warm_start: Option<(usize, f32)>,
    stack: &mut NearestStack,
    mut search_leaf: F,
) -> Option<(usize, f32)> {
    if bvh.nodes.is_empty() {
        return None;
    }
    let mut best_distance_squared = max_distance_squared;
    let mut best_slot = None;
    if let Some((slot, slot_distance_squared)) = warm_start
        && slot_distance_squared < max_distance_squared
    {
        best_distance_squared = slot_distance_squared;
        best_slot = Some(slot);
    }
    let (x, y, z) = (
        Vec4::splat(point.x),
        Vec4::splat(point.y),
        Vec4::splat(point.z),
    );
    stack.clear();
    let mut node_index = 0u32;
    loop {
        let node = &bvh.nodes[node_index as usize];
        let distances = node.distances_squared(x, y, z);
        let within = distances
            .cmplt(Vec4::splat(best_distance_squared))
            .bitmask();
        let distances = distances.to_array();
        // Leaf children first, nearest first: they tighten the bound for the inner ones.
        let mut leaves = within & node.leaf_mask;
        while leaves != 0 {
            let child = nearest_child(leaves, &distances);
            leaves &= !(1 << child);
            if distances[child] < best_distance_squared
                && let Some((slot, distance_squared)) = search_leaf(
                    node.children[child] as usize,
                    usize::from(node.counts[child]),
                    best_distance_squared,
                )
            {
                best_distance_squared = distance_squared;
                best_slot = Some(slot);
            }
        }
        // Then the inner children: go on with the nearest, push the others farthest first.
        let mut inner = within & !node.leaf_mask;
        let mut next = None;
        if inner != 0 {
            let nearest = nearest_child(inner, &distances);
            inner &= !(1 << nearest);
            while inner != 0 {
                let farthest = farthest_child(inner, &distances);
                inner &= !(1 << farthest);
                if distances[farthest] < best_distance_squared {
                    stack.push((node.children[farthest], distances[farthest]));
                }
            }
            if distances[nearest] < best_distance_squared {
                next = Some(node.children[nearest]);
            }
        }
        node_index = match next {
            Some(index) => index,
            None => loop {
                match stack.pop() {
                    None => return best_slot.map(|slot| (slot, best_distance_squared)),
                    Some((index, distance_squared)) if distance_squared < best_distance_squared => {
                        break index;
                    }
                    Some(_) => {}
                }
            },
        };
    }
}

/// The child of `mask` (a non-empty set of child bits) with the smallest distance.
#[inline(always)]
fn nearest_child(mask: u32, distances: &[f32; 4]) -> usize {
    let mut rest = mask;
    let mut best = rest.trailing_zeros() as usize;
    rest &= rest - 1;
    while rest != 0 {
        let child = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        if distances[child] < distances[best] {
            best = child;
        }
    }
    best
}

/// The child of `mask` (a non-empty set of child bits) with the largest distance.
#[inline(always)]
fn farthest_child(mask: u32, distances: &[f32; 4]) -> usize {
    let mut rest = mask;
    let mut worst = rest.trailing_zeros() as usize;
    rest &= rest - 1;
    while rest != 0 {
        let child = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        if distances[child] > distances[worst] {
            worst = child;
        }
    }
    worst
}

/// A leaf search for [`nearest_slot`] from a per-slot distance: `distance_squared(slot, best)`
/// returns the squared distance to the primitive in `slot` (or anything `>= best` when it can
/// tell cheaply that the primitive cannot win).
#[inline(always)]
pub fn search_slots(
    mut distance_squared: impl FnMut(usize, f32) -> f32,
) -> impl FnMut(usize, usize, f32) -> Option<(usize, f32)> {
    move |first, count, mut best| {
        let mut found = None;
        for slot in first..first + count {
            let candidate = distance_squared(slot, best);
            if candidate < best {
                best = candidate;
                found = Some((slot, candidate));
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_point_matches_brute_force() {
        let points: Vec<Vec3A> = (0..500)
            .map(|index| {
                let x = index as f32;
                Vec3A::new(
                    (x * 0.37).sin() * 3.0,
                    (x * 0.11).cos() * 2.0,
                    (x * 0.07).sin(),
                )
            })
            .collect();
        let boxes: Vec<Aabb> = points.iter().map(|&p| Aabb::from_point(p)).collect();
        let bvh = build_bvh(&boxes);
        let bvh4 = Bvh4::from_bvh2(&bvh);
        let mut stack = NearestStack::new();
        for query_index in 0..200 {
            let q = query_index as f32;
            let query = Vec3A::new((q * 0.9).cos() * 4.0, (q * 0.3).sin() * 3.0, q * 0.01 - 1.0);
            let (slot, distance_squared) = nearest_slot(
                &bvh4,
                query,
                f32::INFINITY,
                None,
                &mut stack,
                search_slots(|slot, _| {
                    points[bvh.primitive_indices[slot] as usize].distance_squared(query)
                }),
            )
            .unwrap();
            let brute = points
                .iter()
                .map(|p| p.distance_squared(query))
                .fold(f32::INFINITY, f32::min);
            assert_eq!(distance_squared, brute);
            assert_eq!(
                points[bvh.primitive_indices[slot] as usize].distance_squared(query),
                brute
            );
        }
    }

    #[test]
    fn a_tree_built_from_a_closure_holds_every_primitive_once_in_leaves_of_at_most_four() {
        for count in [1usize, 2, 5, 97, 5000] {
            let boxes: Vec<Aabb> = (0..count)
                .map(|index| {
                    let x = index as f32;
                    let corner = Vec3A::new((x * 0.37).sin(), (x * 0.11).cos(), (x * 0.07).sin());
                    Aabb::new(corner, corner + Vec3A::splat(0.01 * (x % 7.0)))
                })
                .collect();
            let bvh = build_bvh_with(count, |index| boxes[index]);
            assert!(
                bvh.parents.is_empty(),
                "the build's parent links are dropped"
            );
            let mut seen = vec![0; count];
            for node in bvh.nodes.iter().filter(|node| node.is_leaf()) {
                assert!((1..=4).contains(&node.prim_count));
                for slot in node.first_index..node.first_index + node.prim_count {
                    let primitive = bvh.primitive_indices[slot as usize] as usize;
                    seen[primitive] += 1;
                    let inside = boxes[primitive];
                    assert!(node.aabb().min.cmple(inside.min).all());
                    assert!(node.aabb().max.cmpge(inside.max).all());
                }
            }
            assert!(seen.iter().all(|&times| times == 1), "{count} primitives");
        }
    }

    #[test]
    fn the_four_wide_tree_covers_every_slot_once_in_leaves_of_at_most_eight() {
        let boxes: Vec<Aabb> = (0..3000)
            .map(|index| {
                Aabb::from_point(Vec3A::new(
                    (index as f32 * 0.37).sin(),
                    (index as f32 * 0.11).cos(),
                    index as f32 * 1e-3,
                ))
            })
            .collect();
        let bvh = Bvh4::from_bvh2(&build_bvh(&boxes));
        let mut seen = vec![0; boxes.len()];
        let mut widest = 0;
        for node in &bvh.nodes {
            for child in 0..4 {
                if node.leaf_mask & (1 << child) != 0 {
                    let count = u32::from(node.counts[child]);
                    assert!((1..=Bvh4::MAX_LEAF_SLOTS).contains(&count));
                    widest = widest.max(count);
                    for slot in node.children[child]..node.children[child] + count {
                        seen[slot as usize] += 1;
                    }
                }
            }
        }
        assert!(seen.iter().all(|&times| times == 1));
        // Binary leaves hold at most four: a wider leaf is two of them.
        assert!(widest > 4, "no leaf holds two binary leaves");
    }

    #[test]
    fn nothing_within_the_limit_gives_none() {
        let boxes = [Aabb::from_point(Vec3A::ZERO)];
        let bvh = Bvh4::from_bvh2(&build_bvh(&boxes));
        let mut stack = NearestStack::new();
        let found = nearest_slot(
            &bvh,
            Vec3A::splat(10.0),
            1.0,
            None,
            &mut stack,
            search_slots(|_, _| 300.0),
        );
        assert!(found.is_none());
    }
}
