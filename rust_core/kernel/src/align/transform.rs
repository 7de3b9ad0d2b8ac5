//! An affine transform of 3D space as a 3x4 matrix in f64.

use glam::{DVec3, Vec3};

/// An affine transform `x -> linear * x + translation`, stored as 3 rows of 4 (f64).
///
/// Row `r` is `[linear[r][0], linear[r][1], linear[r][2], translation[r]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// The 3x4 matrix, row by row.
    pub rows: [[f64; 4]; 3],
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// The identity.
    pub const IDENTITY: Self = Self {
        rows: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// The transform with linear part `linear` (row-major 3x3) and `translation`.
    #[must_use]
    pub fn from_linear_translation(linear: [[f64; 3]; 3], translation: DVec3) -> Self {
        let t = translation.to_array();
        let mut rows = [[0.0; 4]; 3];
        for (row, out) in rows.iter_mut().enumerate() {
            out[..3].copy_from_slice(&linear[row]);
            out[3] = t[row];
        }
        Self { rows }
    }

    /// The linear (3x3) part, row-major.
    #[must_use]
    pub fn linear(&self) -> [[f64; 3]; 3] {
        let mut linear = [[0.0; 3]; 3];
        for (row, out) in linear.iter_mut().enumerate() {
            out.copy_from_slice(&self.rows[row][..3]);
        }
        linear
    }

    /// The translation part.
    #[must_use]
    pub fn translation(&self) -> DVec3 {
        DVec3::new(self.rows[0][3], self.rows[1][3], self.rows[2][3])
    }

    /// Determinant of the linear part: positive for a transform that keeps handedness.
    #[must_use]
    pub fn determinant(&self) -> f64 {
        let m = self.linear();
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    /// The image of `point`, in f64.
    #[must_use]
    pub fn apply_f64(&self, point: DVec3) -> DVec3 {
        let p = [point.x, point.y, point.z, 1.0];
        let row = |r: usize| (0..4).map(|c| self.rows[r][c] * p[c]).sum::<f64>();
        DVec3::new(row(0), row(1), row(2))
    }

    /// The image of `point`, computed in f64 and rounded to f32.
    #[must_use]
    pub fn apply(&self, point: Vec3) -> Vec3 {
        self.apply_f64(point.as_dvec3()).as_vec3()
    }

    /// The images of `points`.
    #[must_use]
    pub fn apply_all(&self, points: &[Vec3]) -> Vec<Vec3> {
        points.iter().map(|&point| self.apply(point)).collect()
    }

    /// `self` after `first`: the transform `x -> self(first(x))`.
    #[must_use]
    pub fn after(&self, first: &Self) -> Self {
        let mut rows = [[0.0; 4]; 3];
        for (r, out) in rows.iter_mut().enumerate() {
            for (c, value) in out.iter_mut().enumerate() {
                *value = (0..3)
                    .map(|k| self.rows[r][k] * first.rows[k][c])
                    .sum::<f64>();
            }
            out[3] += self.rows[r][3];
        }
        Self { rows }
    }

    /// The 4x4 homogeneous matrix, row-major (last row `0 0 0 1`).
    #[must_use]
    pub fn to_homogeneous(&self) -> [[f64; 4]; 4] {
        [
            self.rows[0],
            self.rows[1],
            self.rows[2],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// True when every entry is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.rows.iter().flatten().all(|value| value.is_finite())
    }
}
