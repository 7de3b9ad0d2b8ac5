//! Landing: at the end, every free point near a trusted, facing surface point lands there as a face-point,
//! unless that turns a corner; the others stay space-points (holes, cavities).

use super::*;

impl EnergySolver {
    /// The layout points after landing (call once finished): face-points where they landed,
    /// anchors and curve targets as their constraints say, space-points elsewhere.
    pub(crate) fn land(&mut self) -> (Vec<LayoutPoint>, usize) {
        let clock = self.profiler.start();
        let landed = self.land_points();
        self.profiler.add(WrapPhase::Landing, clock);
        landed
    }

    /// [`Self::land`] without its profile.
    fn land_points(&mut self) -> (Vec<LayoutPoint>, usize) {
        let vertex_count = self.positions.len();
        let reach = self.landing_distance * LANDING_REACH;
        let normals = self.layout_normals(&self.positions);
        let hits: Vec<Option<SurfaceHit>> = (0..vertex_count)
            .into_par_iter()
            .with_min_len(256)
            .map(|vertex| {
                if self.fixed[vertex].is_some() || self.data_factors[vertex] == 0.0 {
                    return None;
                }
                let hit = self.target.closest_point(self.positions[vertex], reach)?;
                self.surface_trusted(&hit, normals[vertex], self.landing_facing)
                    .then_some(hit)
            })
            .collect();
        let mut candidate = self.positions.clone();
        let mut landing = vec![false; vertex_count];
        for (vertex, hit) in hits.iter().enumerate() {
            if let Some(hit) = hit {
                // Where the face-point is, exactly as it will be read back.
                candidate[vertex] = self
                    .target
                    .interpolate(hit.face_point.triangle, hit.face_point.barycentric);
                landing[vertex] = true;
            }
        }
        // A landing that would turn a corner is not made; refusing one can turn another corner
        // back, so repeat until none turns.
        let before = self.corner_orientations(&self.positions);
        loop {
            let turned = self.turned_corners(&before, &candidate);
            let mut refused = false;
            for vertex in turned {
                if landing[vertex as usize] {
                    landing[vertex as usize] = false;
                    candidate[vertex as usize] = self.positions[vertex as usize];
                    refused = true;
                }
            }
            if !refused {
                break;
            }
        }
        // Refusing every vertex of a turning corner refuses some that could land alone: try
        // those one at a time, nearest first, each kept only if it turns no corner around it.
        let mut retry: Vec<usize> = (0..vertex_count)
            .filter(|&vertex| hits[vertex].is_some() && !landing[vertex])
            .collect();
        retry.sort_by(|&a, &b| {
            let distance = |vertex: usize| hits[vertex].map_or(f32::INFINITY, |hit| hit.distance);
            distance(a).total_cmp(&distance(b))
        });
        for vertex in retry {
            let hit = hits[vertex].expect("retried points have a hit");
            let old = candidate[vertex];
            candidate[vertex] = self
                .target
                .interpolate(hit.face_point.triangle, hit.face_point.barycentric);
            if self.turns_corner_around(vertex as u32, &before, &candidate) {
                candidate[vertex] = old;
            } else {
                landing[vertex] = true;
            }
        }
        let mut points = Vec::with_capacity(vertex_count);
        let mut landed = 0;
        for vertex in 0..vertex_count {
            let point = if let Some(point) = self.fixed_points[vertex] {
                point
            } else if landing[vertex] {
                landed += 1;
                let hit = hits[vertex].expect("a landing point has a hit");
                LayoutPoint::Face(hit.face_point)
            } else {
                LayoutPoint::Space(candidate[vertex])
            };
            points.push(point);
        }
        self.positions = candidate;
        (points, landed)
    }
}
