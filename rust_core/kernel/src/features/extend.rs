//! Extending a curve's open ends along its crease, so that curves run to where the crease ends.
//!
//! The crest test of [`super::ridges`] needs a clear extremum of the fitted curvature, and that
//! fails near where a crease ends (a blend meeting a part's sharp edge, a crease fading out): the
//! neighbourhood of the fit then holds the other surface too, and the curves used to stop about a
//! scale short. Each open end is therefore walked on, as Canny's hysteresis does with edges: a step
//! of a quarter of the scale along the crease direction, projected onto the surface (the closest
//! point) and re-centred across the crease on the peak of the curvature (a parabola through three
//! samples), for as long as the point is still a crest at the *low* threshold (`hysteresis` times
//! the ridge threshold, with a strength that falls off on both sides). Where the surface turns
//! away from the straight step, the part's edge is there: the last step is shortened by bisection
//! to end on it.

use glam::Vec3;

use crate::face_point::SurfaceHit;
use crate::mesh::TargetMesh;

/// A step is a quarter of the scale.
const STEP_SCALES: f32 = 0.25;

/// Where the surface is farther than this fraction of a step from the straight step, it turns
/// away: the crease ends at an edge of the part.
const TURN_FRACTION: f32 = 0.3;

/// Across the crease, the strength must fall by at least this fraction of itself at a quarter of
/// the scale on either side (a crest, not a plateau such as a long cylinder).
const CREST_DROP: f32 = 0.02;

/// Where the crease fades within a step, an edge is looked for when the surface is at least this
/// fraction of the step from the straight line.
const EDGE_FRACTION: f32 = 0.05;

/// The crease direction is followed while within this angle's cosine of the walk's direction
/// (35°), turning halfway to it at each step; where it turns more (the field at a junction),
/// the walk goes straight on.
const FOLLOW_COSINE: f32 = 0.82;

/// An extension never turns by more than this angle's cosine (60°) from the curve's own direction
/// at its end.
const MAX_TURN_COSINE: f32 = 0.5;

/// The most steps taken straight on without a crest across (one scale): beyond, the crease has
/// ended.
const UNCENTRED_STEPS: usize = 4;

/// The most steps one end may take.
const MAX_STEPS: usize = 4096;

/// The per-vertex fields one kind of crease is walked on.
pub(super) struct CreaseField<'a> {
    /// The crease's curvature (`k1` for ridges, `−k2` for valleys).
    pub strength: &'a [f32],
    /// The other curvature, signed the same way.
    pub other: &'a [f32],
    /// The direction along the crease (unit tangent; `d2` for ridges, `d1` for valleys).
    pub along: &'a [Vec3],
    /// The lowest strength a crease point keeps (curvature, 1 / length).
    pub low: f32,
    /// The scale of the curvatures.
    pub scale: f32,
}

impl CreaseField<'_> {
    /// The interpolated strength and other curvature at a surface point.
    fn at(&self, mesh: &TargetMesh, hit: &SurfaceHit) -> (f32, f32) {
        let corners = mesh.triangles()[hit.face_point.triangle as usize];
        let weights = hit.face_point.barycentric.to_array();
        let mut strength = 0.0;
        let mut other = 0.0;
        for (corner, weight) in corners.iter().zip(weights) {
            strength += weight * self.strength[*corner as usize];
            other += weight * self.other[*corner as usize];
        }
        (strength, other)
    }

    /// The crease direction at a surface point, signed to agree with `heading`, in the plane of
    /// the triangle hit.
    fn direction(&self, mesh: &TargetMesh, hit: &SurfaceHit, heading: Vec3) -> Vec3 {
        let triangle = hit.face_point.triangle as usize;
        let corners = mesh.triangles()[triangle];
        let weights = hit.face_point.barycentric.to_array();
        let mut sum = Vec3::ZERO;
        for (corner, weight) in corners.iter().zip(weights) {
            let along = self.along[*corner as usize];
            sum += along * weight * along.dot(heading).signum();
        }
        let normal = mesh.face_normals()[triangle];
        (sum - normal * sum.dot(normal)).normalize_or_zero()
    }

    /// Whether the point is a crease point at the low threshold. Unlike the crest test, the other
    /// curvature may be the larger: where a crease ends on another feature (a blend on a sharp
    /// edge) that one dominates the fit.
    fn strong_enough(&self, strength: f32, other: f32) -> bool {
        strength >= self.low && strength - other >= self.low
    }
}

/// The surface point nearest `point` within `reach`.
fn surface(mesh: &TargetMesh, point: Vec3, reach: f32) -> Option<SurfaceHit> {
    mesh.closest_point(point, reach)
}

/// Points that continue a curve beyond its end `end` heading `heading` (unit, outward), in order
/// from the end outwards (empty when the crease stops there).
pub(super) fn extend_end(
    mesh: &TargetMesh,
    field: &CreaseField<'_>,
    end: Vec3,
    heading: Vec3,
) -> Vec<Vec3> {
    let step = STEP_SCALES * field.scale;
    let mut added = Vec::new();
    if heading == Vec3::ZERO || !step.is_finite() || step <= 0.0 {
        return added;
    }
    let (mut position, mut heading) = (end, heading);
    let initial = heading;
    // Steps taken straight on where no crest was found across, not yet confirmed.
    let mut pending: Vec<Vec3> = Vec::new();
    for _ in 0..MAX_STEPS {
        let predicted = position + heading * step;
        let Some(hit) = surface(mesh, predicted, 2.0 * step) else {
            break;
        };
        if hit.distance > TURN_FRACTION * step {
            // The surface turns away within this step: end on the edge.
            added.append(&mut pending);
            if let Some(last) = edge_point(mesh, position, heading, step) {
                added.push(last);
            }
            break;
        }
        let (strength, other) = field.at(mesh, &hit);
        if !field.strong_enough(strength, other) {
            // The crease fades here, or the step already reaches over an edge (the strength on
            // the far side is another surface's): then end on that edge.
            if hit.distance > EDGE_FRACTION * step {
                added.append(&mut pending);
                if let Some(last) = edge_point(mesh, position, heading, step) {
                    added.push(last);
                }
            }
            break;
        }
        let Some(centred) = recentre(mesh, field, &hit, heading, step) else {
            // No crest across here (the fit near another feature, or a plateau): go straight on,
            // for at most a scale; kept only if an edge or a crest comes within it.
            if pending.len() >= UNCENTRED_STEPS {
                break;
            }
            position = hit.position;
            pending.push(position);
            continue;
        };
        added.append(&mut pending);
        let direction = field.direction(mesh, &centred, heading);
        // Halfway to the field's direction where they agree (the field is noisy near where a
        // crease ends), else straight on; in the plane of the surface either way.
        let normal = mesh.face_normals()[centred.face_point.triangle as usize];
        let turned = if direction.dot(heading) >= FOLLOW_COSINE {
            heading + direction
        } else {
            heading
        };
        let turned = (turned - normal * turned.dot(normal)).normalize_or_zero();
        // Turning further than that from the curve's own direction would follow another feature
        // (a sharp edge where the crease ends), not this crease: then the walk keeps its heading.
        if turned != Vec3::ZERO && turned.dot(initial) >= MAX_TURN_COSINE {
            heading = turned;
        }
        position = centred.position;
        added.push(position);
    }
    added
}

/// The farthest point along `heading` from `position`, within `step`, where the surface still
/// follows the straight line (bisection), on the surface.
fn edge_point(mesh: &TargetMesh, position: Vec3, heading: Vec3, step: f32) -> Option<Vec3> {
    let tolerance = 0.05 * step;
    let (mut inside, mut outside) = (0.0f32, 1.0f32);
    for _ in 0..12 {
        let middle = 0.5 * (inside + outside);
        match surface(mesh, position + heading * step * middle, 2.0 * step) {
            Some(hit) if hit.distance <= tolerance => inside = middle,
            _ => outside = middle,
        }
    }
    if inside <= 0.0 {
        return None;
    }
    surface(mesh, position + heading * step * inside, 2.0 * step).map(|hit| hit.position)
}

/// Moves a crease point across the crease onto the peak of the strength (the vertex of the
/// parabola through samples a quarter of the scale either side, at most a quarter that far, so
/// that a neighbouring feature cannot pull the walk aside); `None`
/// when the parabola does not bend down by [`CREST_DROP`] of the strength (no crest).
fn recentre(
    mesh: &TargetMesh,
    field: &CreaseField<'_>,
    hit: &SurfaceHit,
    heading: Vec3,
    step: f32,
) -> Option<SurfaceHit> {
    let normal = mesh.face_normals()[hit.face_point.triangle as usize];
    let across = normal.cross(heading).normalize_or_zero();
    if across == Vec3::ZERO {
        return Some(*hit);
    }
    let delta = step;
    let centre = field.at(mesh, hit).0;
    let left = surface(mesh, hit.position - across * delta, 2.0 * delta)?;
    let right = surface(mesh, hit.position + across * delta, 2.0 * delta)?;
    let (left, right) = (field.at(mesh, &left).0, field.at(mesh, &right).0);
    let bend = left - 2.0 * centre + right;
    if bend > -CREST_DROP * centre.abs() {
        return None;
    }
    let shift = (0.5 * delta * (left - right) / bend).clamp(-0.25 * delta, 0.25 * delta);
    surface(mesh, hit.position + across * shift, 2.0 * delta)
}
