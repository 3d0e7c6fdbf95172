//! KITTI calibration files, read into the rigid transforms they define.
//!
//! KITTI raw keeps one calibration per recording day: `calib_imu_to_velo.txt` and
//! `calib_velo_to_cam.txt` hold `R:` (9 numbers, row-major) and `T:` (3 numbers) with
//! `p_to = R · p_from + T`; the file name says *from* → *to*, so `calib_imu_to_velo.txt` is
//! `velo_from_imu`. Other keys (`calib_time:`, `delta_f:`, `delta_c:`) are ignored. KITTI
//! odometry keeps one `calib.txt` per sequence, whose `Tr:` line (12 numbers, a 3×4 row-major
//! `[R | t]`) is `cam0_from_velo`; the projection matrices `P0:`..`P3:` are ignored.
//!
//! A rotation block is accepted when it is orthonormal within [`ROTATION_TOLERANCE`] (published
//! files round to 7–13 digits, so never exactly) and has determinant +1; it is then turned into
//! the nearest unit quaternion, so what comes out is an exact rigid transform.

use crate::error::ReadError;
use crate::text::{file_error, line_error, number, read_text};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use std::path::Path;

/// Largest element of `RᵀR − I` accepted for a rotation block read from a file. Files print
/// rotations to 7 or more significant digits, giving errors near 1e-6; 1e-2 still refuses
/// anything that is not meant as a rotation (a scaled matrix, swapped rows, a projection).
pub const ROTATION_TOLERANCE: f64 = 1e-2;

/// Turns a row-major 3×3 matrix into a rotation, or says why it is not one.
pub(crate) fn rotation_from_rows(r: &[f64]) -> Result<UnitQuaternion<f64>, String> {
    let m = Matrix3::from_row_slice(r);
    let defect = (m.transpose() * m - Matrix3::identity()).amax();
    if !defect.is_finite() || defect > ROTATION_TOLERANCE {
        return Err(format!(
            "the 3x3 block is not a rotation (R^T R differs from I by {defect:.3e}, \
             tolerance {ROTATION_TOLERANCE:e})"
        ));
    }
    if m.determinant() <= 0.0 {
        return Err("the 3x3 block is a reflection (determinant -1), not a rotation".into());
    }
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Ok(UnitQuaternion::new_normalize(q.into_inner()))
}

/// The rigid transform of a row-major 3×4 matrix `[R | t]` (12 numbers).
pub(crate) fn isometry_from_3x4(v: &[f64; 12]) -> Result<Isometry3<f64>, String> {
    let rotation = rotation_from_rows(&[v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]])?;
    Ok(Isometry3::from_parts(
        Translation3::new(v[3], v[7], v[11]),
        rotation,
    ))
}

/// The row-major 3×4 matrix `[R | t]` of a rigid transform, the inverse of [`isometry_from_3x4`].
pub(crate) fn rows_3x4(iso: &Isometry3<f64>) -> [f64; 12] {
    let r = iso.rotation.to_rotation_matrix().into_inner();
    let t = iso.translation.vector;
    [
        r[(0, 0)],
        r[(0, 1)],
        r[(0, 2)],
        t.x,
        r[(1, 0)],
        r[(1, 1)],
        r[(1, 2)],
        t.y,
        r[(2, 0)],
        r[(2, 1)],
        r[(2, 2)],
        t.z,
    ]
}

/// A calibration key's numbers and the 1-based line they were on.
type KeyValues = Option<(usize, Vec<f64>)>;

/// Reads the `key: numbers` lines of a calibration file whose key is in `wanted`, returning the
/// values of each wanted key with its line (None when absent). A key given twice is an error: the
/// file would be ambiguous.
fn read_keys<const K: usize>(
    path: &Path,
    wanted: [(&str, usize); K],
) -> Result<[KeyValues; K], ReadError> {
    let text = read_text(path)?;
    let mut found: [KeyValues; K] = std::array::from_fn(|_| None);
    for (i, line) in text.lines().enumerate() {
        let line_number = i + 1;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let Some((key, values)) = line.split_once(':') else {
            return Err(line_error(
                path,
                line_number,
                "expected `key: values` (a KITTI calibration line)",
            ));
        };
        let key = key.trim();
        let Some(k) = wanted.iter().position(|(w, _)| *w == key) else {
            continue;
        };
        if let Some((first, _)) = &found[k] {
            return Err(line_error(
                path,
                line_number,
                format!("`{key}:` given again (first on line {first})"),
            ));
        }
        let count = wanted[k].1;
        let mut numbers = Vec::with_capacity(count);
        for word in values.split_whitespace() {
            if numbers.len() == count {
                return Err(line_error(
                    path,
                    line_number,
                    format!("`{key}:` needs {count} numbers, found more"),
                ));
            }
            numbers.push(number(word).map_err(|m| line_error(path, line_number, m))?);
        }
        if numbers.len() != count {
            return Err(line_error(
                path,
                line_number,
                format!("`{key}:` needs {count} numbers, found {}", numbers.len()),
            ));
        }
        found[k] = Some((line_number, numbers));
    }
    Ok(found)
}

/// Reads a KITTI raw rigid calibration (`R:` 9 numbers row-major, `T:` 3 numbers) into the
/// transform `to_from_from` with `p_to = R · p_from + T`.
///
/// # Errors
///
/// [`ReadError`]: the file cannot be read, `R:` or `T:` is missing, given twice, has the wrong
/// count or a non-number, or `R` is not a rotation (with the line).
pub fn read_rigid_calib(path: &Path) -> Result<Isometry3<f64>, ReadError> {
    let [r, t] = read_keys(path, [("R", 9), ("T", 3)])?;
    let missing = |key: &str| {
        file_error(
            path,
            format!(
                "no `{key}:` line (a KITTI raw calibration has `R:` with 9 numbers and `T:` with 3)"
            ),
        )
    };
    let (r_line, r) = r.ok_or_else(|| missing("R"))?;
    let (_, t) = t.ok_or_else(|| missing("T"))?;
    let rotation = rotation_from_rows(&r).map_err(|m| line_error(path, r_line, m))?;
    Ok(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        rotation,
    ))
}

/// Reads KITTI raw `calib_imu_to_velo.txt` as `velo_from_imu` (`p_velo = R · p_imu + T`).
///
/// # Errors
///
/// As [`read_rigid_calib`].
pub fn read_velo_from_imu(path: &Path) -> Result<Isometry3<f64>, ReadError> {
    read_rigid_calib(path)
}

/// Reads KITTI raw `calib_velo_to_cam.txt` as `cam0_from_velo` (unrectified camera 0).
///
/// # Errors
///
/// As [`read_rigid_calib`].
pub fn read_cam0_from_velo(path: &Path) -> Result<Isometry3<f64>, ReadError> {
    read_rigid_calib(path)
}

/// Reads a KITTI odometry `calib.txt`: its `Tr:` line (12 numbers, 3×4 row-major) as
/// `cam0_from_velo`. `Tr_velo_to_cam:` (the name in KITTI's object and tracking sets) is accepted
/// as well, but not both.
///
/// # Errors
///
/// [`ReadError`]: unreadable file, no `Tr:` line, wrong count, non-number, or not a rigid
/// transform (with the line).
pub fn read_odometry_cam0_from_velo(path: &Path) -> Result<Isometry3<f64>, ReadError> {
    let [tr, tr_long] = read_keys(path, [("Tr", 12), ("Tr_velo_to_cam", 12)])?;
    let (line, values) = match (tr, tr_long) {
        (Some(a), None) | (None, Some(a)) => a,
        (Some(_), Some((line, _))) => {
            return Err(line_error(
                path,
                line,
                "both `Tr:` and `Tr_velo_to_cam:` given; keep one",
            ));
        }
        (None, None) => {
            return Err(file_error(
                path,
                "no `Tr:` line (a KITTI odometry calib.txt has `Tr:` with 12 numbers, \
                 cam0_from_velo as a 3x4 row-major matrix)",
            ));
        }
    };
    let mut v = [0.0; 12];
    v.copy_from_slice(&values);
    isometry_from_3x4(&v).map_err(|m| line_error(path, line, m))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn rigid_calib_maps_from_to() {
        let dir = tempfile::tempdir().unwrap();
        // R = Rz(90°): x_from -> y_to. T = (1, 2, 3).
        let path = write(
            &dir,
            "c.txt",
            "calib_time: 25-May-2012 16:47:16\nR: 0 -1 0 1 0 0 0 0 1\nT: 1 2 3\ndelta_f: 0 0\n",
        );
        let to_from_from = read_rigid_calib(&path).unwrap();
        let p = to_from_from * Point3::new(1.0, 0.0, 0.0);
        assert!((p - Point3::new(1.0, 3.0, 3.0)).norm() < 1e-12, "{p}");
    }

    #[test]
    fn rigid_calib_errors_name_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            (
                "R: 1 0 0 0 1 0 0 0\nT: 0 0 0\n",
                "c.txt:1:",
                "needs 9 numbers, found 8",
            ),
            (
                "R: 1 0 0 0 1 0 0 0 1 0\nT: 0 0 0\n",
                "c.txt:1:",
                "found more",
            ),
            (
                "R: 1 0 0 0 1 0 0 0 1\nT: 0 x 0\n",
                "c.txt:2:",
                "`x` is not a number",
            ),
            ("R: 1 0 0 0 1 0 0 0 1\n", "c.txt:", "no `T:` line"),
            ("T: 0 0 0\n", "c.txt:", "no `R:` line"),
            (
                "R: 2 0 0 0 2 0 0 0 2\nT: 0 0 0\n",
                "c.txt:1:",
                "not a rotation",
            ),
            (
                "R: -1 0 0 0 1 0 0 0 1\nT: 0 0 0\n",
                "c.txt:1:",
                "reflection",
            ),
            (
                "R: 1 0 0 0 1 0 0 0 1\nT: 0 0 0\nT: 1 1 1\n",
                "c.txt:3:",
                "given again",
            ),
            ("R 1 0 0\n", "c.txt:1:", "key: values"),
            (
                "R: 1 0 0 0 1 0 0 0 nan\nT: 0 0 0\n",
                "c.txt:1:",
                "not finite",
            ),
        ];
        for (text, place, what) in cases {
            let path = write(&dir, "c.txt", text);
            let err = read_rigid_calib(&path).unwrap_err().to_string();
            assert!(err.contains(place) && err.contains(what), "{text:?}: {err}");
        }
    }

    #[test]
    fn odometry_calib_reads_tr() {
        let dir = tempfile::tempdir().unwrap();
        // KITTI odometry sequence 00's Tr, and P lines that must be ignored.
        let text = "P0: 7.188560000000e+02 0 6.071928000000e+02 0 0 7.188560000000e+02 1.852157000000e+02 0 0 0 1 0\n\
                    Tr: 4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 \
                    -7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 \
                    9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01\n";
        let path = write(&dir, "calib.txt", text);
        let cam0_from_velo = read_odometry_cam0_from_velo(&path).unwrap();
        // Velodyne forward (x) is camera forward (z); velodyne left (y) is camera -x.
        let fwd = cam0_from_velo.rotation * Vector3::x();
        let left = cam0_from_velo.rotation * Vector3::y();
        assert!((fwd - Vector3::z()).norm() < 0.02 && (left + Vector3::x()).norm() < 0.02);
        assert!((cam0_from_velo.translation.vector.z + 0.292).abs() < 1e-3);

        let path = write(&dir, "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
        let err = read_odometry_cam0_from_velo(&path).unwrap_err().to_string();
        assert!(err.contains("no `Tr:` line"), "{err}");
        let path = write(&dir, "calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1\n");
        let err = read_odometry_cam0_from_velo(&path).unwrap_err().to_string();
        assert!(
            err.contains("calib.txt:1:") && err.contains("needs 12"),
            "{err}"
        );
    }

    #[test]
    fn rotation_tolerance_and_nearest_rotation() {
        // A rotation printed to 7 digits is accepted and comes out exactly orthonormal.
        let c = 0.8660254;
        let q = rotation_from_rows(&[c, -0.5, 0.0, 0.5, c, 0.0, 0.0, 0.0, 1.0]).unwrap();
        assert!((q.angle() - std::f64::consts::FRAC_PI_6).abs() < 1e-6);
        let m = q.to_rotation_matrix().into_inner();
        assert!((m.transpose() * m - Matrix3::identity()).amax() < 1e-14);
    }

    #[test]
    fn shared_kitti_imu_to_velo_lever_arm() {
        let Some(path) = geodata::testdata::shared_file(
            "data/lidar/kitti-raw-0013/2011_09_26/calib_imu_to_velo.txt",
        ) else {
            return;
        };
        let velo_from_imu = read_velo_from_imu(&path).unwrap();
        let imu_from_velo = velo_from_imu.inverse();
        // KITTI's sensor drawing: the Velodyne is 0.81 m ahead of, 0.32 m right of and 0.80 m
        // above the IMU (x forward, y left, z up in both frames, nearly aligned). `-T` alone
        // (ignoring the rotation) matches that to 1 cm.
        let t = imu_from_velo.translation.vector;
        let minus_t = -velo_from_imu.translation.vector;
        assert!(
            (minus_t - Vector3::new(0.81, -0.32, 0.80)).norm() < 0.01,
            "{minus_t}"
        );
        // The exact lever arm is `-Rᵀ T`: the calibration's 0.0148 rad roll between the frames,
        // times the 0.80 m height, moves y by 1.2 cm, to (0.8105, -0.3071, 0.8027). So x and z
        // agree with the drawing within 1 cm, y within 1.5 cm.
        assert!(
            (t.x - 0.81).abs() < 0.01 && (t.z - 0.80).abs() < 0.01,
            "{t}"
        );
        assert!((t.y + 0.32).abs() < 0.015, "{t}");
        assert!(
            (t - Vector3::new(0.8105, -0.3071, 0.8027)).norm() < 1e-3,
            "{t}"
        );
        assert!(imu_from_velo.rotation.angle() < 0.02);
    }
}
