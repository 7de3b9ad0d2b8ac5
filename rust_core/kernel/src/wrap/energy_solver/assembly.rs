//! The global step's system: its diagonal (proximal and data weights) and its right-hand side (the
//! data points and the shape terms' targets), row by row in parallel.
//!
//! A right-hand side scattered term by term would add into shared rows; here each term's target
//! is computed once in parallel, then each row gathers its own terms, in the order a serial
//! scatter would add them (term by term, entry by entry), so that every row is the same to the
//! bit whatever the threads and whoever steals what.

use super::*;

/// Per vertex, the terms whose stencils have an entry on it, in term order (a term once per such
/// entry): a transpose of the stencils, made once.
#[derive(Debug, Clone)]
pub(super) struct TermsOfVertex {
    /// Start of each vertex's terms; one more than there are vertices.
    offsets: Vec<u32>,
    terms: Vec<u32>,
}

impl TermsOfVertex {
    /// The transpose of `stencils` over `vertex_count` vertices.
    pub(super) fn new(stencils: &Stencils, vertex_count: usize) -> Self {
        let mut offsets = vec![0u32; vertex_count + 1];
        for &vertex in &stencils.vertices {
            offsets[vertex as usize + 1] += 1;
        }
        for vertex in 0..vertex_count {
            offsets[vertex + 1] += offsets[vertex];
        }
        let mut next = offsets.clone();
        let mut terms = vec![0u32; stencils.vertices.len()];
        for term in 0..stencils.len() {
            for (vertex, _) in stencils.entries(term) {
                let slot = &mut next[vertex as usize];
                terms[*slot as usize] = term as u32;
                *slot += 1;
            }
        }
        Self { offsets, terms }
    }

    /// The terms with an entry on `vertex`, in term order.
    fn of(&self, vertex: u32) -> &[u32] {
        &self.terms
            [self.offsets[vertex as usize] as usize..self.offsets[vertex as usize + 1] as usize]
    }
}

impl EnergySolver {
    /// Per row of the system: its extra diagonal (the proximal weight, and the data weight of its
    /// correspondence) and its right-hand side.
    pub(super) fn assemble_rows(
        &self,
        correspondences: &[Option<Correspondence>],
        data_weight: f64,
    ) -> (Vec<f64>, Vec<DVec3>) {
        let proximal = PROXIMAL_WEIGHT * EDGE_WEIGHT;
        // Each term's target once (a term touches two or three rows), dropped before the solve.
        let wanted: Vec<DVec3> = (0..self.stencils.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|term| self.term_target(term))
            .collect();
        self.system
            .vertex_of_row()
            .par_iter()
            .with_min_len(1024)
            .map(|&vertex| {
                let mut diagonal = proximal;
                let mut right_hand_side = self.positions[vertex as usize].as_dvec3() * proximal;
                if let Some((weight, point)) = correspondences[vertex as usize] {
                    let weight = f64::from(weight) * data_weight;
                    diagonal += weight;
                    right_hand_side += point.as_dvec3() * weight;
                }
                let mut previous = None;
                let mut occurrence = 0;
                for &term in self.terms_of_vertex.of(vertex) {
                    // A term on the vertex twice adds its entries in their order.
                    occurrence = if previous == Some(term) {
                        occurrence + 1
                    } else {
                        0
                    };
                    previous = Some(term);
                    let term = term as usize;
                    let coefficient = self
                        .stencils
                        .entries(term)
                        .filter(|&(on, _)| on == vertex)
                        .nth(occurrence)
                        .map_or(0.0, |(_, coefficient)| coefficient);
                    let weight = self.stencils.weights[term];
                    right_hand_side += wanted[term] * (weight * coefficient);
                }
                (diagonal, right_hand_side)
            })
            .unzip()
    }
}
