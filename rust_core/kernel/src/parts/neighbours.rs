//! The nearest surface vertices of a point: a uniform grid over the surface's vertices, searched in
//! growing shells of cells until no unvisited cell can hold a nearer vertex.

use glam::DVec3;

/// Vertices bucketed in a uniform grid of cubic cells.
pub(super) struct PointGrid {
    low: DVec3,
    high: DVec3,
    cell: f64,
    dims: [usize; 3],
    /// The first entry of each cell in `items` (one more than there are cells).
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl PointGrid {
    /// A grid with about `per_cell` of the (finite, non-empty) `points` in each cell of a uniform
    /// spread, and at most four cells per point.
    pub(super) fn new(points: &[DVec3], per_cell: usize) -> Self {
        let (low, high) = points.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(low, high), &point| (low.min(point), high.max(point)),
        );
        let extent = (high - low).max(DVec3::splat((high - low).length() * 1e-3 + 1e-12));
        let volume = extent.x * extent.y * extent.z;
        let mut cell = (volume * per_cell.max(1) as f64 / points.len() as f64).cbrt();
        let cells_along = |cell: f64| (extent / cell).ceil().max(DVec3::ONE);
        while {
            let along = cells_along(cell);
            along.x * along.y * along.z > 4.0 * points.len() as f64 + 8.0
        } {
            cell *= 1.25;
        }
        let along = cells_along(cell);
        let dims = [along.x as usize, along.y as usize, along.z as usize];
        let mut grid = Self {
            low,
            high,
            cell,
            dims,
            starts: Vec::new(),
            items: Vec::new(),
        };
        let cell_of: Vec<usize> = points
            .iter()
            .map(|&point| grid.index(grid.cell_of(point)))
            .collect();
        let mut counts = vec![0u32; dims[0] * dims[1] * dims[2] + 1];
        for &cell in &cell_of {
            counts[cell + 1] += 1;
        }
        for index in 1..counts.len() {
            counts[index] += counts[index - 1];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; points.len()];
        for (point, &cell) in cell_of.iter().enumerate() {
            items[fill[cell] as usize] = point as u32;
            fill[cell] += 1;
        }
        grid.starts = counts;
        grid.items = items;
        grid
    }

    fn cell_of(&self, point: DVec3) -> [usize; 3] {
        let relative = ((point - self.low) / self.cell).floor();
        std::array::from_fn(|axis| {
            let value = relative[axis].max(0.0);
            (value as usize).min(self.dims[axis] - 1)
        })
    }

    fn index(&self, cell: [usize; 3]) -> usize {
        (cell[2] * self.dims[1] + cell[1]) * self.dims[0] + cell[0]
    }

    /// The `count` points nearest to `query` (fewer when there are fewer), nearest first, each with
    /// its distance.
    pub(super) fn nearest(&self, points: &[DVec3], query: DVec3, count: usize) -> Vec<(u32, f64)> {
        let mut best: Vec<(u32, f64)> = Vec::with_capacity(count + 1);
        let centre = self.cell_of(query);
        // How far the query is outside the grid's box: shells are that much nearer than they look.
        let outside = (query - query.clamp(self.low, self.high)).length();
        let widest = self.dims.into_iter().max().unwrap_or(1);
        for ring in 0..=widest {
            let ring_i = ring as isize;
            for dz in -ring_i..=ring_i {
                for dy in -ring_i..=ring_i {
                    for dx in -ring_i..=ring_i {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != ring_i {
                            continue;
                        }
                        let cell = [
                            centre[0] as isize + dx,
                            centre[1] as isize + dy,
                            centre[2] as isize + dz,
                        ];
                        if (0..3)
                            .any(|axis| cell[axis] < 0 || cell[axis] >= self.dims[axis] as isize)
                        {
                            continue;
                        }
                        let index = self.index(cell.map(|value| value as usize));
                        let (start, end) =
                            (self.starts[index] as usize, self.starts[index + 1] as usize);
                        for &item in &self.items[start..end] {
                            let distance = points[item as usize].distance(query);
                            if best.len() < count || distance < best[best.len() - 1].1 {
                                let at = best.partition_point(|&(_, other)| other <= distance);
                                best.insert(at, (item, distance));
                                best.truncate(count);
                            }
                        }
                    }
                }
            }
            // Every unvisited cell is at least `ring` whole cells from the query's own cell.
            let bound = ring as f64 * self.cell - outside;
            if best.len() == count && best[count - 1].1 <= bound {
                break;
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_finds_what_a_brute_force_search_finds() {
        let points: Vec<DVec3> = (0..500)
            .map(|i| {
                let t = f64::from(i);
                DVec3::new(
                    (t * 0.37).sin() * 3.0,
                    (t * 0.11).cos(),
                    (t * 0.05).sin() * 0.2,
                )
            })
            .collect();
        let grid = PointGrid::new(&points, 8);
        for query in [
            DVec3::ZERO,
            DVec3::new(2.0, 0.5, 0.1),
            DVec3::new(40.0, -9.0, 3.0),
        ] {
            let found = grid.nearest(&points, query, 12);
            let mut brute: Vec<f64> = points.iter().map(|point| point.distance(query)).collect();
            brute.sort_by(f64::total_cmp);
            let distances: Vec<f64> = found.iter().map(|&(_, distance)| distance).collect();
            assert_eq!(distances, brute[..12].to_vec());
        }
    }
}
