//! Feature detection in one call: curvatures, regions and curves, with the inputs checked.

use super::curvature::{PrincipalCurvatures, check_scale, principal_curvatures};
use super::regions::{FeatureRegion, classify_regions};
use super::ridges::{CurveSettings, FeatureCurve, feature_curves};
use crate::error::KernelError;
use crate::mesh::TargetMesh;
use crate::validate::{MAX_COORDINATE, SettingRange, check_setting};

/// Settings of [`detect_features`]. Lengths are in model units; thresholds are dimensionless
/// (a curvature `k` is compared as `k × scale`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureSettings {
    /// Radius over which the surface is fitted: detail and noise below it are ignored. For blend
    /// centre-lines, about the blends' radius.
    pub scale: f32,
    /// Below this `|k| × scale` a direction counts as flat (default 0.1).
    pub flat_threshold: f32,
    /// `k × scale` a ridge or valley must reach (default 0.25).
    pub ridge_threshold: f32,
    /// Curves shorter than this are dropped (default twice the scale).
    pub min_length: f32,
    /// Curve pieces whose ends are closer than this and continue each other are joined (default
    /// the scale).
    pub join_distance: f32,
}

impl FeatureSettings {
    /// The ranges of the thresholds and lengths (field, what it is, range): the thresholds
    /// (`|k| × scale`, dimensionless) from 0 to 1,000; the lengths from 0 to
    /// [`MAX_COORDINATE`].
    pub const RANGES: [(&'static str, &'static str, SettingRange); 4] = [
        (
            "flat_threshold",
            "flat threshold",
            SettingRange::closed(0.0, 1000.0),
        ),
        (
            "ridge_threshold",
            "ridge threshold",
            SettingRange::closed(0.0, 1000.0),
        ),
        (
            "min_length",
            "minimum curve length",
            SettingRange::closed(0.0, MAX_COORDINATE as f64),
        ),
        (
            "join_distance",
            "join distance",
            SettingRange::closed(0.0, MAX_COORDINATE as f64),
        ),
    ];

    /// The defaults for a scale.
    #[must_use]
    pub fn with_scale(scale: f32) -> Self {
        Self {
            scale,
            flat_threshold: 0.1,
            ridge_threshold: 0.25,
            min_length: 2.0 * scale,
            join_distance: scale,
        }
    }
}

/// Everything [`detect_features`] finds.
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// Principal curvatures and directions per vertex.
    pub curvatures: PrincipalCurvatures,
    /// The region of each vertex.
    pub regions: Vec<FeatureRegion>,
    /// Ridge and valley curves.
    pub curves: Vec<FeatureCurve>,
}

/// Curvatures, regions and feature curves of a mesh.
///
/// # Errors
/// [`KernelError::InvalidScale`]; [`KernelError::InvalidArgument`] for a threshold, length or
/// distance that is negative or not finite; [`KernelError::FlatSurface`] when no vertex bends
/// beyond the flat threshold (a plane: there is nothing to classify or trace).
pub fn detect_features(
    mesh: &TargetMesh,
    settings: &FeatureSettings,
) -> Result<Features, KernelError> {
    check_scale(mesh, settings.scale)?;
    for (name, label, range) in FeatureSettings::RANGES {
        let value = match name {
            "flat_threshold" => settings.flat_threshold,
            "ridge_threshold" => settings.ridge_threshold,
            "min_length" => settings.min_length,
            _ => settings.join_distance,
        };
        check_setting(name, label, value, range)?;
    }
    let curvatures = principal_curvatures(mesh, settings.scale)?;
    let largest = curvatures
        .k1
        .iter()
        .chain(&curvatures.k2)
        .fold(0.0f32, |largest, k| largest.max(k.abs()))
        * settings.scale;
    if largest < settings.flat_threshold {
        return Err(KernelError::FlatSurface {
            largest,
            threshold: settings.flat_threshold,
        });
    }
    let regions = classify_regions(&curvatures, settings.flat_threshold);
    let curves = feature_curves(
        mesh,
        &curvatures,
        &CurveSettings {
            ridge_threshold: settings.ridge_threshold,
            min_length: settings.min_length,
            join_distance: settings.join_distance,
        },
    );
    Ok(Features {
        curvatures,
        regions,
        curves,
    })
}
