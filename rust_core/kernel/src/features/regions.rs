//! Concave / convex / flat (and saddle) regions from the principal curvatures.

use super::curvature::PrincipalCurvatures;

/// The kind of surface around a vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum FeatureRegion {
    /// Both curvatures below the threshold: flat at this scale.
    Flat = 0,
    /// Bends away from its normal (a ridge, a blend of an outer edge, a bump): `k1` above the
    /// threshold and `k2` not below minus it.
    Convex = 1,
    /// Bends towards its normal (a valley, a fillet of an inner edge, a dent).
    Concave = 2,
    /// Convex one way and concave the other (`k1` above, `k2` below minus the threshold).
    Saddle = 3,
}

/// The region of every vertex.
///
/// The threshold is relative to the scale, so that one value suits a mesh of any size: a
/// curvature `k` counts when `|k| × scale ≥ flat_threshold`, i.e. when over the fitting radius
/// the surface leaves its tangent plane by more than `flat_threshold / 2` of that radius
/// (`k scale² / 2`). The default, 0.1, calls a surface flat while it bends by less than 5 % of
/// the scale across it.
#[must_use]
pub fn classify_regions(
    curvatures: &PrincipalCurvatures,
    flat_threshold: f32,
) -> Vec<FeatureRegion> {
    let threshold = flat_threshold / curvatures.scale;
    curvatures
        .k1
        .iter()
        .zip(&curvatures.k2)
        .map(|(&k1, &k2)| match (k1 >= threshold, k2 <= -threshold) {
            (false, false) => FeatureRegion::Flat,
            (true, false) => FeatureRegion::Convex,
            (false, true) => FeatureRegion::Concave,
            (true, true) => FeatureRegion::Saddle,
        })
        .collect()
}
