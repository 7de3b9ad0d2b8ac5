//! Feature detection in one call: curvatures, regions and curves, with the inputs checked.

use super::curvature::{PrincipalCurvatures, check_scale, principal_curvatures};
use super::regions::{FeatureRegion, classify_regions};
use super::ridges::{CurveSettings, FeatureCurve, feature_curves};
use super::scale::{LAYOUT_EDGE_RANGE, automatic_scale};
use crate::error::KernelError;
use crate::mesh::TargetMesh;
use crate::validate::{MAX_COORDINATE, SettingRange, check_setting};

/// Curves shorter than this many scales are dropped by default: a layout edge chain following a
/// curve has edges of about a scale, and a chain of fewer than three edges hardly constrains.
pub const MIN_LENGTH_SCALES: f32 = 3.0;

/// Curve ends closer than this many scales that continue each other are joined by default (two: a
/// crease that noise breaks into pieces is one curve again).
pub const JOIN_DISTANCE_SCALES: f32 = 2.0;

/// Settings of [`detect_features`]. Lengths are in model units; thresholds are dimensionless
/// (a curvature `k` is compared as `k × scale`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureSettings {
    /// Radius over which the surface is fitted: detail and noise below it are ignored. For blend
    /// centre-lines, about the blends' radius. 0 (the default): automatic, see
    /// [`super::automatic_scale`].
    pub scale: f32,
    /// With an automatic scale, the median edge length of the layout the curves are for (0: no
    /// layout, the scale then comes from the target alone). Ignored with a given scale.
    pub layout_edge_length: f32,
    /// Below this `|k| × scale` a direction counts as flat (default 0.1).
    pub flat_threshold: f32,
    /// `k × scale` a ridge or valley must reach somewhere along it (default 0.25).
    pub ridge_threshold: f32,
    /// The fraction of the ridge threshold a curve keeps along the rest of its length and while
    /// its ends are extended along the crease (default 0.5; 1: no hysteresis, no extension
    /// beyond the full threshold).
    pub hysteresis: f32,
    /// Curves shorter than this are dropped (`None`, the default: three times the scale).
    pub min_length: Option<f32>,
    /// Curve pieces whose ends are closer than this and continue each other are joined (`None`,
    /// the default: the scale).
    pub join_distance: Option<f32>,
}

impl Default for FeatureSettings {
    /// The automatic scale (from the target alone) and the default thresholds.
    fn default() -> Self {
        Self {
            scale: 0.0,
            layout_edge_length: 0.0,
            flat_threshold: 0.1,
            ridge_threshold: 0.25,
            hysteresis: 0.5,
            min_length: None,
            join_distance: None,
        }
    }
}

impl FeatureSettings {
    /// The ranges of the thresholds and lengths (field, what it is, range): the thresholds
    /// (`|k| × scale`, dimensionless) from 0 to 1,000; the hysteresis from 0 to 1; the lengths
    /// from 0 to [`MAX_COORDINATE`].
    pub const RANGES: [(&'static str, &'static str, SettingRange); 5] = [
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
            "hysteresis",
            "hysteresis (a fraction of the ridge threshold)",
            SettingRange::closed(0.0, 1.0),
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

    /// The defaults with a given scale.
    #[must_use]
    pub fn with_scale(scale: f32) -> Self {
        Self {
            scale,
            ..Self::default()
        }
    }

    /// The defaults with the automatic scale for a layout whose median edge length is
    /// `layout_edge_length`.
    #[must_use]
    pub fn for_layout(layout_edge_length: f32) -> Self {
        Self {
            layout_edge_length,
            ..Self::default()
        }
    }

    /// The minimum curve length at `scale`: the one given, else [`MIN_LENGTH_SCALES`] scales.
    #[must_use]
    pub fn min_length_at(&self, scale: f32) -> f32 {
        self.min_length.unwrap_or(MIN_LENGTH_SCALES * scale)
    }

    /// The join distance at `scale`: the one given, else [`JOIN_DISTANCE_SCALES`] scales.
    #[must_use]
    pub fn join_distance_at(&self, scale: f32) -> f32 {
        self.join_distance.unwrap_or(JOIN_DISTANCE_SCALES * scale)
    }
}

/// Everything [`detect_features`] finds.
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// The scale used (the one given, or the automatic one).
    pub scale: f32,
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
/// [`KernelError::InvalidScale`] for a scale that is negative, not finite or beyond the mesh's
/// diagonal (0 is the automatic scale), or an automatic one on a mesh without extent;
/// [`KernelError::InvalidArgument`] for a threshold, length, distance or layout edge length that
/// is out of its range; [`KernelError::FlatSurface`] when no vertex bends beyond the flat
/// threshold (a plane: there is nothing to classify or trace).
pub fn detect_features(
    mesh: &TargetMesh,
    settings: &FeatureSettings,
) -> Result<Features, KernelError> {
    let scale = if settings.scale == 0.0 {
        automatic_scale(mesh, settings.layout_edge_length)?
    } else {
        check_setting(
            "layout_edge_length",
            "layout edge length",
            settings.layout_edge_length,
            LAYOUT_EDGE_RANGE,
        )?;
        settings.scale
    };
    check_scale(mesh, scale)?;
    for (name, label, range) in FeatureSettings::RANGES {
        let value = match name {
            "flat_threshold" => settings.flat_threshold,
            "ridge_threshold" => settings.ridge_threshold,
            "hysteresis" => settings.hysteresis,
            "min_length" => settings.min_length_at(scale),
            _ => settings.join_distance_at(scale),
        };
        check_setting(name, label, value, range)?;
    }
    let curvatures = principal_curvatures(mesh, scale)?;
    let largest = curvatures
        .k1
        .iter()
        .chain(&curvatures.k2)
        .fold(0.0f32, |largest, k| largest.max(k.abs()))
        * scale;
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
            hysteresis: settings.hysteresis,
            min_length: settings.min_length_at(scale),
            join_distance: settings.join_distance_at(scale),
        },
    );
    Ok(Features {
        scale,
        curvatures,
        regions,
        curves,
    })
}
