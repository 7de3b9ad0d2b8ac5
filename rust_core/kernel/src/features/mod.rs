//! Feature detection on a target mesh (the paper's section 3.2 and Figure 9):
//! principal curvatures fitted over a scale, concave / convex / flat regions, and ridge and valley
//! curves (the centre-lines of blends) that can serve as curve constraints, and the pairing of a
//! layout's feature lines with them.

pub mod curvature;
pub mod detect;
mod extend;
pub mod join;
pub mod neighborhood;
pub mod pairing;
pub mod regions;
pub mod ridges;
pub mod scale;

pub use curvature::{PrincipalCurvatures, principal_curvatures};
pub use detect::{FeatureSettings, Features, detect_features};
pub use pairing::{
    FreeReason, LinePairing, PairSettings, TargetCurve, TargetCurveKind, pair_lines,
};
pub use regions::{FeatureRegion, classify_regions};
pub use ridges::{CurveSettings, FeatureCurve, FeatureCurveKind, feature_curves};
pub use scale::{automatic_scale, mean_edge_length};
