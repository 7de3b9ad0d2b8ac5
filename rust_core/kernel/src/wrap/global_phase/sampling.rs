//! Sparse closest-point queries for the stiff levels: one query per cluster of nearby vertices.
//!
//! The stiff levels ask only for the layout's shape over many rings (their rotations and stretches
//! are smoothed over 32 to 128 rings, their data term is wide), yet the closest-point queries cost
//! more than half of each of their iterations. Here the layout's vertices are covered by clusters:
//! a **sample** and the vertices within a few edges of it. Only the samples are queried; every
//! other vertex of a cluster is pulled onto its sample's tangent plane (the plane of the triangle
//! its closest point lies on), with the Welsch weight of its own distance to that plane. On a
//! plane the answer is the one its own query would give; on a curved surface it is off by about
//! `d² / 2R` (`d` the distance to the sample, `R` the radius of curvature), a small part of the
//! stiff levels' Welsch widths. The local levels query every vertex.

use glam::Vec3;

use crate::layout::LayoutStructure;

/// The cluster owner of a vertex that has none (not queried).
const NO_SAMPLE: u32 = u32::MAX;

/// The layout's clusters: per vertex, the sample whose query it shares.
#[derive(Debug, Clone)]
pub(crate) struct DataSamples {
    /// Per vertex, its sample (itself for a sample), or [`NO_SAMPLE`].
    owner: Vec<u32>,
    /// Per vertex, whether it is a sample.
    pub(crate) is_sample: Vec<bool>,
}

impl DataSamples {
    /// Clusters of the vertices `queried` says (the others belong to none): in vertex order, each
    /// vertex not yet in a cluster becomes a sample, and the queried vertices within `hops` edges
    /// of it (through queried vertices) not yet in a cluster join its own.
    pub(crate) fn new(structure: &LayoutStructure, queried: &[bool], hops: usize) -> Self {
        let count = structure.vertex_count;
        let mut owner = vec![NO_SAMPLE; count];
        let mut is_sample = vec![false; count];
        let (mut frontier, mut next) = (Vec::new(), Vec::new());
        for vertex in 0..count {
            if !queried[vertex] || owner[vertex] != NO_SAMPLE {
                continue;
            }
            let sample = vertex as u32;
            is_sample[vertex] = true;
            owner[vertex] = sample;
            frontier.clear();
            frontier.push(sample);
            for _ in 0..hops {
                next.clear();
                for &here in &frontier {
                    for &other in structure.neighbors_of(here) {
                        let index = other as usize;
                        if queried[index] && owner[index] == NO_SAMPLE {
                            owner[index] = sample;
                            next.push(other);
                        }
                    }
                }
                std::mem::swap(&mut frontier, &mut next);
            }
        }
        Self { owner, is_sample }
    }

    /// The sample whose query `vertex` shares, when it belongs to a cluster and is not a sample.
    pub(crate) fn sample_of(&self, vertex: usize) -> Option<u32> {
        let sample = self.owner[vertex];
        (sample != NO_SAMPLE && !self.is_sample[vertex]).then_some(sample)
    }

    /// How many samples there are.
    #[cfg(test)]
    pub(crate) fn sample_count(&self) -> usize {
        self.is_sample.iter().filter(|&&sample| sample).count()
    }

    /// Fills in the correspondences (Welsch weight, point pulled to) of the vertices that are not
    /// samples from their sample's: the vertex at `positions` projected onto the plane through
    /// its sample's point with normal `plane_normal(sample)` (`None`: no correspondence), its
    /// weight `weight(vertex, distance to the plane)`; a vertex whose sample has none has none.
    pub(crate) fn share(
        &self,
        positions: &[Vec3],
        correspondences: &mut [Option<(f32, Vec3)>],
        plane_normal: impl Fn(u32) -> Option<Vec3>,
        weight: impl Fn(usize, f32) -> f32,
    ) {
        let planes: Vec<Option<(Vec3, Vec3)>> = correspondences
            .iter()
            .enumerate()
            .map(|(vertex, correspondence)| {
                let (_, point) = (*correspondence)?;
                self.is_sample[vertex]
                    .then(|| plane_normal(vertex as u32))
                    .flatten()
                    .map(|normal| (point, normal))
            })
            .collect();
        for (vertex, correspondence) in correspondences.iter_mut().enumerate() {
            let sample = self.owner[vertex];
            if sample == NO_SAMPLE || self.is_sample[vertex] {
                continue;
            }
            *correspondence = planes[sample as usize].and_then(|(point, normal)| {
                let position = positions[vertex];
                let distance = normal.dot(position - point);
                let projected = position - normal * distance;
                let weight = weight(vertex, distance.abs());
                (weight > 0.0 && projected.is_finite()).then_some((weight, projected))
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: u32) -> (LayoutStructure, Vec<Vec3>) {
        super::super::tests::grid_of(n)
    }

    #[test]
    fn every_queried_vertex_is_within_hops_of_its_sample_and_samples_are_few() {
        let (structure, _) = grid(20);
        let count = structure.vertex_count;
        let mut queried = vec![true; count];
        queried[0] = false;
        for hops in [1, 2] {
            let samples = DataSamples::new(&structure, &queried, hops);
            assert_eq!(samples.owner[0], NO_SAMPLE);
            for vertex in 1..count {
                let sample = samples.owner[vertex] as usize;
                assert!(sample < count && samples.is_sample[sample]);
                let (a, b) = (vertex as u32 % 21, vertex as u32 / 21);
                let (c, d) = (sample as u32 % 21, sample as u32 / 21);
                assert!(
                    a.abs_diff(c) + b.abs_diff(d) <= hops as u32,
                    "{vertex} {sample}"
                );
            }
            // A cover, not every vertex: in scan order on a grid, about one vertex in two with
            // one hop, fewer with two.
            let bound = if hops == 1 {
                count * 6 / 10
            } else {
                count * 4 / 10
            };
            assert!(samples.sample_count() < bound, "{}", samples.sample_count());
            assert!(!samples.is_sample[0]);
        }
        assert_eq!(
            DataSamples::new(&structure, &queried, 0).sample_count(),
            count - 1
        );
    }

    #[test]
    fn shared_correspondences_are_the_projections_onto_the_samples_planes() {
        let (structure, rest) = grid(6);
        let queried = vec![true; structure.vertex_count];
        let samples = DataSamples::new(&structure, &queried, 2);
        // The layout floats at varying heights over the plane z = 1 (normal +z); each sample's
        // correspondence is its projection, as a query would give.
        let positions: Vec<Vec3> = rest
            .iter()
            .map(|&p| p + Vec3::Z * (2.0 + 0.1 * p.x))
            .collect();
        let mut correspondences: Vec<Option<(f32, Vec3)>> = positions
            .iter()
            .enumerate()
            .map(|(vertex, &p)| {
                samples.is_sample[vertex].then_some((0.5, Vec3::new(p.x, p.y, 1.0)))
            })
            .collect();
        samples.share(
            &positions,
            &mut correspondences,
            |_| Some(Vec3::Z),
            |_, distance| 1.0 / (1.0 + distance),
        );
        for (vertex, &position) in positions.iter().enumerate() {
            let (weight, point) = correspondences[vertex].unwrap();
            assert!(point.abs_diff_eq(Vec3::new(position.x, position.y, 1.0), 1e-5));
            if !samples.is_sample[vertex] {
                let wanted = 1.0 / (1.0 + (position.z - 1.0));
                assert!((weight - wanted).abs() < 1e-5, "{weight} {wanted}");
            }
        }
        // A sample without a plane leaves its cluster without correspondences.
        let mut none = vec![None; positions.len()];
        samples.share(&positions, &mut none, |_| Some(Vec3::Z), |_, _| 1.0);
        assert!(none.iter().all(Option::is_none));
        let mut some = correspondences.clone();
        samples.share(&positions, &mut some, |_| None, |_, _| 1.0);
        for (vertex, correspondence) in some.iter().enumerate() {
            assert_eq!(correspondence.is_some(), samples.is_sample[vertex]);
        }
    }
}
