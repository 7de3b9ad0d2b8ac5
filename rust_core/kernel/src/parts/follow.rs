//! [`SurfaceFollower`]: parts moved by the motion of the layout's surface around them.

use glam::{DQuat, DVec3};
use rayon::prelude::*;

use super::neighbours::PointGrid;
use crate::align::fit::horn_rotation;
use crate::align::linear_algebra::symmetric_eigen;
use crate::error::KernelError;
use crate::validate::{SettingRange, check_setting};

/// How parts are bound to the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowSettings {
    /// Surface vertices each vertex of a rigid piece is bound to (its nearest at rest): 1 … 1024.
    /// More reach further and average the surface's motion over a wider region.
    pub neighbours: usize,
    /// Surface vertices each soft part vertex is bound to: 1 … 1024. A soft vertex follows its own
    /// neighbourhood alone, so it needs a wider one than a rigid piece (whose vertices pool
    /// theirs) to average out the unevenness of the surface's motion.
    pub soft_neighbours: usize,
    /// Whether the parts also take the surface's uniform scale around them (else rotation and
    /// translation alone: after an alignment has scaled the template, a part keeps its size, as an
    /// eyeball does when the face around it gains weight).
    pub scale: bool,
    /// Reweighting rounds of a rigid piece's fit: 0 … 16. Each round fits the motion again with the
    /// surface vertices that the last fit carries badly weighted down (Geman-McClure: a misfit of
    /// [`ROBUST_SCALE`] times the weighted median keeps a quarter of its weight), so that a piece
    /// follows the part of its surroundings that moves as one body (an eyeball its brow and cheek)
    /// rather than skin that folds over it (a closing eyelid). The weights vary smoothly with the
    /// misfits, so a symmetric motion keeps a part on the mirror plane symmetric. 0: one plain
    /// weighted fit.
    pub robust_rounds: usize,
}

impl Default for FollowSettings {
    fn default() -> Self {
        Self {
            neighbours: 64,
            soft_neighbours: 256,
            scale: false,
            robust_rounds: 0,
        }
    }
}

impl FollowSettings {
    /// Checks the settings' ranges.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] naming the setting out of its range.
    pub fn validate(&self) -> Result<(), KernelError> {
        check_setting(
            "neighbours",
            "number of surface neighbours",
            self.neighbours as f64,
            SettingRange::closed(1.0, MAX_NEIGHBOURS),
        )?;
        check_setting(
            "soft_neighbours",
            "number of surface neighbours of a soft part vertex",
            self.soft_neighbours as f64,
            SettingRange::closed(1.0, MAX_NEIGHBOURS),
        )?;
        check_setting(
            "robust_rounds",
            "number of reweighting rounds of a rigid piece's fit",
            self.robust_rounds as f64,
            SettingRange::closed(0.0, MAX_ROBUST_ROUNDS),
        )
    }
}

/// The most reweighting rounds of a rigid piece's fit.
const MAX_ROBUST_ROUNDS: f64 = 16.0;
/// The misfit, in weighted medians, at which a surface vertex keeps a quarter of its weight in the
/// next round of a rigid piece's fit (Geman-McClure's scale).
pub const ROBUST_SCALE: f64 = 1.0;

/// The most surface neighbours a part vertex may be bound to.
const MAX_NEIGHBOURS: f64 = 1024.0;

/// One part vertex's (or a rigid piece's) surface vertices and weights (summing to 1).
type Binding = Vec<(u32, f64)>;

/// Parts bound to the layout's surface at rest; [`SurfaceFollower::apply`] moves them by the
/// surface's motion since. See the module's documentation for the rule.
#[derive(Debug, Clone)]
pub struct SurfaceFollower {
    surface_count: usize,
    settings: FollowSettings,
    surface_rest: Vec<DVec3>,
    part_rest: Vec<DVec3>,
    /// Per part vertex: `None` when it belongs to a rigid piece, else its own binding.
    soft: Vec<Option<Binding>>,
    /// Per rigid piece: its part vertices and the binding of the surface around all of them.
    rigid: Vec<(Vec<u32>, Binding)>,
}

impl SurfaceFollower {
    /// Binds the parts at rest (`part_rest`, piece `pieces[i]` of vertex `i`) to the surface at
    /// rest (`surface_rest`). `rigid[p]` says whether piece `p` keeps its shape; every piece
    /// number must be below `rigid.len()`.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] for no surface vertex, a piece number without a flag or
    /// settings out of range; [`KernelError::LengthMismatch`] unless there is one piece number per
    /// part vertex; [`KernelError::NonFinite`] / [`KernelError::CoordinateOutOfRange`] for a bad
    /// coordinate.
    pub fn new(
        surface_rest: &[DVec3],
        part_rest: &[DVec3],
        pieces: &[u32],
        rigid: &[bool],
        settings: FollowSettings,
    ) -> Result<Self, KernelError> {
        settings.validate()?;
        if surface_rest.is_empty() {
            return Err(KernelError::InvalidArgument {
                name: "surface",
                reason:
                    "there is no surface vertex for the parts to follow (every vertex is a part)"
                        .to_owned(),
            });
        }
        if pieces.len() != part_rest.len() {
            return Err(KernelError::LengthMismatch {
                what: "part vertices and their piece numbers",
                first: part_rest.len(),
                second: pieces.len(),
            });
        }
        if let Some(vertex) = pieces
            .iter()
            .position(|&piece| piece as usize >= rigid.len())
        {
            return Err(KernelError::InvalidArgument {
                name: "pieces",
                reason: format!(
                    "part vertex {vertex} is in piece {} but only {} pieces have a rigid flag",
                    pieces[vertex],
                    rigid.len()
                ),
            });
        }
        check_points("surface vertex", surface_rest)?;
        check_points("part vertex", part_rest)?;
        let grid = PointGrid::new(surface_rest, settings.neighbours);
        let bindings: Vec<Binding> = part_rest
            .par_iter()
            .zip(pieces)
            .map(|(&point, &piece)| {
                let count = if rigid[piece as usize] {
                    settings.neighbours
                } else {
                    settings.soft_neighbours
                };
                bind(&nearest_with_ties(&grid, surface_rest, point, count))
            })
            .collect();
        let mut rigid_pieces: Vec<Option<(Vec<u32>, Vec<f64>)>> = vec![None; rigid.len()];
        let mut soft = Vec::with_capacity(part_rest.len());
        for (vertex, (binding, &piece)) in bindings.into_iter().zip(pieces).enumerate() {
            if !rigid[piece as usize] {
                soft.push(Some(binding));
                continue;
            }
            soft.push(None);
            let (members, weights) = rigid_pieces[piece as usize]
                .get_or_insert_with(|| (Vec::new(), vec![0.0; surface_rest.len()]));
            members.push(vertex as u32);
            for (surface, weight) in binding {
                weights[surface as usize] += weight;
            }
        }
        let rigid = rigid_pieces
            .into_iter()
            .flatten()
            .map(|(members, weights)| {
                let total = members.len() as f64;
                let binding = weights
                    .iter()
                    .enumerate()
                    .filter(|&(_, &weight)| weight > 0.0)
                    .map(|(surface, &weight)| (surface as u32, weight / total))
                    .collect();
                (members, binding)
            })
            .collect();
        Ok(Self {
            surface_count: surface_rest.len(),
            settings,
            surface_rest: surface_rest.to_vec(),
            part_rest: part_rest.to_vec(),
            soft,
            rigid,
        })
    }

    /// Number of part vertices.
    #[must_use]
    pub fn part_count(&self) -> usize {
        self.part_rest.len()
    }

    /// The part vertices moved by the surface's motion from its rest to `surface_now` (one
    /// position per surface vertex, in the order given at rest), in parallel.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] for another count of surface vertices;
    /// [`KernelError::NonFinite`] / [`KernelError::CoordinateOutOfRange`] for a bad coordinate.
    pub fn apply(&self, surface_now: &[DVec3]) -> Result<Vec<DVec3>, KernelError> {
        if surface_now.len() != self.surface_count {
            return Err(KernelError::LengthMismatch {
                what: "surface positions now and at rest",
                first: surface_now.len(),
                second: self.surface_count,
            });
        }
        check_points("surface vertex", surface_now)?;
        let motion = |binding: &Binding| {
            Motion::fit(
                binding,
                &self.surface_rest,
                surface_now,
                self.settings.scale,
            )
        };
        let mut moved: Vec<DVec3> = self
            .soft
            .par_iter()
            .zip(&self.part_rest)
            .map(|(binding, &point)| {
                binding
                    .as_ref()
                    .map_or(point, |binding| motion(binding).apply(point))
            })
            .collect();
        let rigid_motions: Vec<Motion> = self
            .rigid
            .par_iter()
            .map(|(_, binding)| {
                Motion::robust_fit(binding, &self.surface_rest, surface_now, self.settings)
            })
            .collect();
        for ((members, _), motion) in self.rigid.iter().zip(rigid_motions) {
            for &vertex in members {
                moved[vertex as usize] = motion.apply(self.part_rest[vertex as usize]);
            }
        }
        Ok(moved)
    }
}

/// Surface vertices as far as the farthest of the `count` nearest within this fraction of its
/// distance are bound too: the mirror images of a symmetric layout's vertices are equally far
/// from a part vertex on the mirror plane, and binding one of them and not the other would make
/// the part's motion lopsided.
const TIE_TOLERANCE: f64 = 1e-6;
/// The most surface vertices bound beyond `count` for being as far as its farthest.
const MAX_TIES: usize = 16;

/// The `count` nearest surface vertices of `point` (nearest first, with distances) and those
/// tied with the farthest of them (see [`TIE_TOLERANCE`]).
fn nearest_with_ties(
    grid: &PointGrid,
    surface: &[DVec3],
    point: DVec3,
    count: usize,
) -> Vec<(u32, f64)> {
    let mut nearest = grid.nearest(surface, point, count + MAX_TIES);
    if let Some(&(_, farthest)) = nearest.get(count.saturating_sub(1)) {
        let limit = farthest * (1.0 + TIE_TOLERANCE) + f64::MIN_POSITIVE;
        let kept = nearest.partition_point(|&(_, distance)| distance <= limit);
        nearest.truncate(kept.max(count));
    }
    nearest
}

fn check_points(what: &'static str, points: &[DVec3]) -> Result<(), KernelError> {
    points.iter().enumerate().try_for_each(|(index, point)| {
        if !point.is_finite() {
            return Err(KernelError::NonFinite { what, index });
        }
        crate::validate::check_coordinate(what, index, point.as_vec3())
    })
}

/// Weights of a point's nearest surface vertices (`nearest`: nearest first, with distances):
/// inverse squared distance (softened by the nearest one's distance), tapered to a small value at
/// one and a half times the farthest one's distance; normalised to sum 1.
fn bind(nearest: &[(u32, f64)]) -> Binding {
    let first = nearest.first().map_or(0.0, |&(_, distance)| distance);
    let last = nearest.last().map_or(0.0, |&(_, distance)| distance);
    let soften = (first * first)
        .max(last * last * 1e-6)
        .max(f64::MIN_POSITIVE);
    let reach = 1.5 * last.max(f64::MIN_POSITIVE);
    let mut binding: Binding = nearest
        .iter()
        .map(|&(surface, distance)| {
            let taper = (1.0 - (distance / reach).powi(2)).max(0.0).powi(2);
            (surface, taper / (distance * distance + soften))
        })
        .collect();
    let total: f64 = binding.iter().map(|&(_, weight)| weight).sum();
    for entry in &mut binding {
        entry.1 = if total > 0.0 {
            entry.1 / total
        } else {
            1.0 / nearest.len() as f64
        };
    }
    binding
}

/// The weighted median of `(value, weight)` pairs (weights summing to about 1); sorts them.
fn weighted_median(pairs: &mut [(f64, f64)]) -> f64 {
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = pairs.iter().map(|&(_, weight)| weight).sum();
    let mut running = 0.0;
    for &(value, weight) in pairs.iter() {
        running += weight;
        if running >= 0.5 * total {
            return value;
        }
    }
    pairs.last().map_or(0.0, |&(value, _)| value)
}

/// A similarity taking a neighbourhood at rest to the same neighbourhood now.
struct Motion {
    rest_centre: DVec3,
    now_centre: DVec3,
    rotation: DQuat,
    scale: f64,
}

/// A neighbourhood whose second principal spread is below this fraction of its first is a line
/// (or a point): its rotation is not determined, it moves by its translation alone.
const FLAT_SPREAD: f64 = 1e-6;

impl Motion {
    /// The weighted best similarity (Horn's rotation; Umeyama's scale when `with_scale`) of the
    /// binding's surface vertices from `rest` to `now`.
    fn fit(binding: &Binding, rest: &[DVec3], now: &[DVec3], with_scale: bool) -> Self {
        let mut rest_centre = DVec3::ZERO;
        let mut now_centre = DVec3::ZERO;
        for &(surface, weight) in binding {
            rest_centre += weight * rest[surface as usize];
            now_centre += weight * now[surface as usize];
        }
        let mut cross = [[0.0; 3]; 3];
        let mut spread = [[0.0; 3]; 3];
        let mut rest_variance = 0.0;
        for &(surface, weight) in binding {
            let a = (rest[surface as usize] - rest_centre).to_array();
            let b = (now[surface as usize] - now_centre).to_array();
            for row in 0..3 {
                for column in 0..3 {
                    cross[row][column] += weight * a[row] * b[column];
                    spread[row][column] += weight * a[row] * a[column];
                }
                rest_variance += weight * a[row] * a[row];
            }
        }
        let (values, _) = symmetric_eigen(spread);
        if !(values[0] > 0.0 && values[1] > FLAT_SPREAD * values[0]) {
            return Self {
                rest_centre,
                now_centre,
                rotation: DQuat::IDENTITY,
                scale: 1.0,
            };
        }
        let rotation = horn_rotation(&cross);
        let mut scale = 1.0;
        if with_scale {
            let mut aligned = 0.0;
            for &(surface, weight) in binding {
                let a = rotation * (rest[surface as usize] - rest_centre);
                aligned += weight * a.dot(now[surface as usize] - now_centre);
            }
            if aligned > 0.0 {
                scale = aligned / rest_variance;
            }
        }
        Self {
            rest_centre,
            now_centre,
            rotation,
            scale,
        }
    }

    /// [`Motion::fit`] reweighted `settings.robust_rounds` times (see
    /// [`FollowSettings::robust_rounds`]): the surface vertices it carries worst lose their weight.
    fn robust_fit(
        binding: &Binding,
        rest: &[DVec3],
        now: &[DVec3],
        settings: FollowSettings,
    ) -> Self {
        let mut motion = Self::fit(binding, rest, now, settings.scale);
        // The neighbourhood's size: misfits below a millionth of it are exact.
        let size = binding
            .iter()
            .map(|&(surface, weight)| weight * rest[surface as usize].distance(motion.rest_centre))
            .sum::<f64>();
        for _round in 0..settings.robust_rounds {
            let misfits: Vec<(f64, f64)> = binding
                .iter()
                .map(|&(surface, weight)| {
                    let carried = motion.apply(rest[surface as usize]);
                    (carried.distance(now[surface as usize]), weight)
                })
                .collect();
            let median = weighted_median(&mut misfits.clone());
            if median.is_nan() || median <= 1e-6 * size {
                break;
            }
            let scale = ROBUST_SCALE * median;
            let reweighted: Binding = binding
                .iter()
                .zip(&misfits)
                .map(|(&(surface, weight), &(misfit, _))| {
                    let ratio = misfit / scale;
                    (surface, weight / (1.0 + ratio * ratio).powi(2))
                })
                .collect();
            let total: f64 = reweighted.iter().map(|&(_, weight)| weight).sum();
            if total.is_nan() || total <= 0.0 {
                break;
            }
            let normalised: Binding = reweighted
                .into_iter()
                .map(|(surface, weight)| (surface, weight / total))
                .collect();
            motion = Self::fit(&normalised, rest, now, settings.scale);
        }
        motion
    }

    fn apply(&self, point: DVec3) -> DVec3 {
        self.now_centre + self.scale * (self.rotation * (point - self.rest_centre))
    }
}
