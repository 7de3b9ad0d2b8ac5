//! Joining curve pieces that continue each other: ends close together, directions in line.

use glam::Vec3;

/// Length of a polyline (with the closing segment of a loop).
#[must_use]
pub fn polyline_length(points: &[Vec3], closed: bool) -> f32 {
    let open: f32 = points
        .windows(2)
        .map(|pair| pair[0].distance(pair[1]))
        .sum();
    match (closed, points.first(), points.last()) {
        (true, Some(first), Some(last)) => open + first.distance(*last),
        _ => open,
    }
}

/// The outward direction at one end of a polyline, over up to `reach` of its length.
#[must_use]
pub fn end_tangent(points: &[Vec3], at_start: bool, reach: f32) -> Vec3 {
    let count = points.len();
    let point = |index: usize| {
        if at_start {
            points[index]
        } else {
            points[count - 1 - index]
        }
    };
    let end = point(0);
    let mut inner = end;
    let mut travelled = 0.0;
    for index in 1..count {
        travelled += point(index - 1).distance(point(index));
        inner = point(index);
        if travelled >= reach {
            break;
        }
    }
    (end - inner).normalize_or_zero()
}

/// Joins open chains whose ends are within `distance` and continue each other (the two end
/// directions within 30° of straight on, and each within 45° of the gap between them); closes a
/// chain whose own ends so meet. Closest pairs first. Ends meeting at an angle, such as the
/// edges of a box at a corner, stay apart.
#[must_use]
pub fn join_chains(chains: Vec<(Vec<Vec3>, bool)>, distance: f32) -> Vec<(Vec<Vec3>, bool)> {
    let straight_limit = 0.866;
    let gap_limit = std::f32::consts::FRAC_1_SQRT_2;
    let mut result: Vec<(Vec<Vec3>, bool)> = Vec::new();
    let mut open: Vec<Vec<Vec3>> = Vec::new();
    for (points, closed) in chains {
        if closed || points.len() < 2 {
            if points.len() >= 2 {
                result.push((points, closed));
            }
        } else {
            open.push(points);
        }
    }
    // End `2c` is the start of chain c, `2c + 1` its end.
    let ends: Vec<(Vec3, Vec3)> = open
        .iter()
        .flat_map(|points| {
            let reach = distance.max(polyline_length(points, false) * 0.25);
            let reach = reach.min(polyline_length(points, false) * 0.5);
            [
                (points[0], end_tangent(points, true, reach)),
                (points[points.len() - 1], end_tangent(points, false, reach)),
            ]
        })
        .collect();
    let mut candidates: Vec<(f32, usize, usize)> = Vec::new();
    for a in 0..ends.len() {
        for b in a + 1..ends.len() {
            let gap = ends[b].0 - ends[a].0;
            let length = gap.length();
            if length > distance {
                continue;
            }
            let straight = ends[a].1.dot(-ends[b].1) >= straight_limit;
            let compatible = if length <= distance * 0.05 {
                straight
            } else {
                let direction = gap / length;
                straight
                    && ends[a].1.dot(direction) >= gap_limit
                    && ends[b].1.dot(-direction) >= gap_limit
            };
            let same_chain = a / 2 == b / 2;
            let long_enough = !same_chain || polyline_length(&open[a / 2], false) > 3.0 * distance;
            if compatible && long_enough {
                candidates.push((length, a, b));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut partner = vec![usize::MAX; ends.len()];
    for (_, a, b) in candidates {
        if partner[a] == usize::MAX && partner[b] == usize::MAX {
            partner[a] = b;
            partner[b] = a;
        }
    }
    // Walk the chains through their linked ends.
    let mut visited = vec![false; open.len()];
    let walk_from = |chain: usize, enter_end: usize, visited: &mut Vec<bool>| {
        let mut points: Vec<Vec3> = Vec::new();
        let (mut chain, mut enter_end) = (chain, enter_end);
        loop {
            visited[chain] = true;
            let piece = &open[chain];
            if enter_end == 2 * chain {
                points.extend(piece.iter().copied());
            } else {
                points.extend(piece.iter().rev().copied());
            }
            let exit_end = enter_end ^ 1;
            let next = partner[exit_end];
            if next == usize::MAX {
                return (points, false);
            }
            if visited[next / 2] {
                return (points, true);
            }
            chain = next / 2;
            enter_end = next;
        }
    };
    for chain in 0..open.len() {
        if visited[chain] {
            continue;
        }
        for end in [2 * chain, 2 * chain + 1] {
            if partner[end] == usize::MAX && !visited[chain] {
                result.push(walk_from(chain, end, &mut visited));
            }
        }
    }
    for chain in 0..open.len() {
        if !visited[chain] {
            result.push(walk_from(chain, 2 * chain, &mut visited));
        }
    }
    result
}
