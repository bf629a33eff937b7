//! Rotations for the wire: quaternions (scalar first, as the contract orders them),
//! rotation matrices (columns are a frame's axes in the parent frame) and the camera frames
//! of the egodriver contract.

use fogline_types::clip::CameraCalib;

/// A quaternion `[w, x, y, z]`.
pub(crate) type Quat = [f64; 4];
/// A rotation matrix, `m[row][column]`; column `j` is axis `j` of the rotated frame.
pub(crate) type Mat3 = [[f64; 3]; 3];

/// The rotation by `yaw` about `z` (left positive).
pub(crate) fn quat_from_yaw(yaw: f64) -> Quat {
    let (s, c) = (yaw / 2.0).sin_cos();
    [c, 0.0, 0.0, s]
}

/// Normalises `q`; a zero (or non-finite) quaternion is the identity, as a
/// default-constructed protobuf message must read.
fn normalised(q: Quat) -> Quat {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if !(n.is_finite() && n > 1e-12) {
        return [1.0, 0.0, 0.0, 0.0];
    }
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

/// The heading of the rotated `x` axis: the first angle of a z-y-x Euler decomposition.
pub(crate) fn yaw_of(q: Quat) -> f64 {
    let [w, x, y, z] = normalised(q);
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// The matrix of `q`.
pub(crate) fn matrix(q: Quat) -> Mat3 {
    let [w, x, y, z] = normalised(q);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The quaternion of a rotation matrix (Shepperd's method), with `w ≥ 0`.
pub(crate) fn quat_from_matrix(m: Mat3) -> Quat {
    let tr = m[0][0] + m[1][1] + m[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            s / 4.0,
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
        [
            (m[2][1] - m[1][2]) / s,
            s / 4.0,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
        [
            (m[0][2] - m[2][0]) / s,
            (m[0][1] + m[1][0]) / s,
            s / 4.0,
            (m[1][2] + m[2][1]) / s,
        ]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
        [
            (m[1][0] - m[0][1]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            s / 4.0,
        ]
    };
    let q = normalised(q);
    if q[0] < 0.0 {
        [-q[0], -q[1], -q[2], -q[3]]
    } else {
        q
    }
}

/// Wraps an angle to `(−π, π]`.
pub(crate) fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let r = a.rem_euclid(t);
    if r > std::f64::consts::PI { r - t } else { r }
}

/// How `rig_to_camera` declares a camera's orientation (the contract revision).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CameraFrame {
    /// Revision 1: the camera body (x along the optical axis, y left, z up).
    Body,
    /// Revision 2, AlpaSim's convention: the optical frame (x right, y down, z along the
    /// optical axis).
    Optical,
}

/// The rotation of a camera's frame in the rig, for `rig_to_camera`.
pub(crate) fn camera_rotation(calib: &CameraCalib, frame: CameraFrame) -> Mat3 {
    let [f, r, d] = calib.axes();
    let cols = match frame {
        CameraFrame::Optical => [r, d, f],
        CameraFrame::Body => [f, [-r[0], -r[1], -r[2]], [-d[0], -d[1], -d[2]]],
    };
    let mut m = [[0.0; 3]; 3];
    for (j, col) in cols.iter().enumerate() {
        for i in 0..3 {
            m[i][j] = col[i];
        }
    }
    m
}

/// Yaw (left positive), pitch (down positive) and the magnitude of the roll (radians) of a
/// camera whose frame has rotation `m` in the rig.
pub(crate) fn camera_angles(m: Mat3, frame: CameraFrame) -> (f64, f64, f64) {
    let col = |j: usize| [m[0][j], m[1][j], m[2][j]];
    let (fwd, right) = match frame {
        CameraFrame::Optical => (col(2), col(0)),
        CameraFrame::Body => {
            let l = col(1);
            (col(0), [-l[0], -l[1], -l[2]])
        }
    };
    let yaw = fwd[1].atan2(fwd[0]);
    let pitch = (-fwd[2]).atan2(fwd[0].hypot(fwd[1]));
    // A camera without roll has its right axis level: (sin yaw, −cos yaw, 0).
    let (sy, cy) = yaw.sin_cos();
    let level = right[0] * sy - right[1] * cy;
    let roll = level.clamp(-1.0, 1.0).acos();
    (yaw, pitch, roll)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fogline_types::clip::CameraId;

    #[test]
    fn quaternion_matrix_round_trip() {
        for &yaw in &[0.0, 0.3, -2.0, 3.1] {
            let q = quat_from_yaw(yaw);
            assert!((yaw_of(q) - yaw).abs() < 1e-12);
            let back = quat_from_matrix(matrix(q));
            let dot: f64 = (0..4).map(|i| back[i] * q[i]).sum();
            assert!((dot.abs() - 1.0).abs() < 1e-12);
        }
        assert_eq!(yaw_of([0.0; 4]), 0.0);
    }

    #[test]
    fn camera_frames_give_back_yaw_and_pitch() {
        for id in CameraId::ALL {
            let mut calib = CameraCalib::standard(id, 64, 32);
            calib.pitch_rad = 0.1;
            for frame in [CameraFrame::Optical, CameraFrame::Body] {
                let m = matrix(quat_from_matrix(camera_rotation(&calib, frame)));
                let (yaw, pitch, roll) = camera_angles(m, frame);
                assert!((yaw - calib.yaw_rad).abs() < 1e-9, "{id} {frame:?}");
                assert!((pitch - 0.1).abs() < 1e-9);
                assert!(roll < 1e-6);
            }
        }
    }

    #[test]
    fn optical_frame_of_a_level_front_camera() {
        // Optical z (the axis) along rig x, optical x (right) along −y, y (down) along −z.
        let calib = CameraCalib::standard(CameraId::FrontWide, 64, 32);
        let m = camera_rotation(&calib, CameraFrame::Optical);
        assert_eq!([m[0][2], m[1][2], m[2][2]], [1.0, 0.0, 0.0]);
        assert!((m[1][0] + 1.0).abs() < 1e-12 && (m[2][1] + 1.0).abs() < 1e-12);
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
    }
}
