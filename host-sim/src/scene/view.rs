//! The view transform of a camera (thesis §1.3): the look-at basis, the orthographic and
//! perspective maps to the unit screen cube and back, the depth range. See
//! [`super::camera`] for the conventions and how a scene goes through it; this module knows
//! no mesh.

use anyhow::{bail, Result};
use parry3d_f64::math::Vector;

/// How the camera projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Orthographic, with the view's width (= height) in world units.
    Ortho {
        /// View width.
        width: f64,
    },
    /// Perspective, with the field of view (horizontal = vertical) in degrees.
    Perspective {
        /// Field of view, degrees, in (0, 180).
        fov_deg: f64,
    },
}

/// A camera as a user gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: [f64; 3],
    /// The point the eye looks at.
    pub look_at: [f64; 3],
    /// The up direction (need not be perpendicular to the view direction).
    pub up: [f64; 3],
    /// Projection.
    pub projection: Projection,
    /// Near-plane depth (default: from the scene's bounds).
    pub near: Option<f64>,
    /// Far-plane depth (default: from the scene's bounds).
    pub far: Option<f64>,
}

impl Camera {
    /// The Cornell box's published camera: eye (278, 273, −800) looking along +z, up +y, 39.3°.
    pub const CORNELL: Camera = Camera {
        eye: [278.0, 273.0, -800.0],
        look_at: [278.0, 273.0, 0.0],
        up: [0.0, 1.0, 0.0],
        projection: Projection::Perspective { fov_deg: 39.3 },
        near: None,
        far: None,
    };
}

/// A camera resolved against a scene: an orthonormal basis and the depth range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Eye position (world).
    pub eye: Vector,
    /// View-space x (toward the image's left), y (up), z (forward), in world coordinates.
    pub axes: [Vector; 3],
    /// Perspective (else orthographic).
    pub perspective: bool,
    /// Orthographic: the view width; perspective: 2·tan(fov/2), the width at unit depth.
    pub width: f64,
    /// Near-plane depth.
    pub near: f64,
    /// Far-plane depth.
    pub far: f64,
}

fn v3(a: [f64; 3], what: &str) -> Result<Vector> {
    if a.iter().any(|c| !c.is_finite()) {
        bail!("camera: {what} {a:?} is not finite");
    }
    Ok(Vector::from(a))
}

impl View {
    /// A one-line description: eye, projection and depth range (world units).
    pub fn describe(&self) -> String {
        let e = self.eye;
        let projection = if self.perspective {
            format!("perspective {:.1}°", 2.0 * (self.width / 2.0).atan().to_degrees())
        } else {
            format!("orthographic, width {}", self.width)
        };
        format!("camera at ({}, {}, {}), {projection}, depth {:.0} ..= {:.0}", e.x, e.y, e.z, self.near, self.far)
    }

    /// Resolve `cam` for an `n`-grid against the world points `points` (the scene's used
    /// vertices and lights): checks the camera, and sets near and far from the points' depth
    /// range where not given ([`DEPTH_MARGIN_VOXELS`]).
    pub fn new(cam: &Camera, n: u32, points: impl Iterator<Item = [f64; 3]>) -> Result<View> {
        let (eye, at, up) = (v3(cam.eye, "eye")?, v3(cam.look_at, "look-at point")?, v3(cam.up, "up vector")?);
        let Some(fwd) = (at - eye).try_normalize() else {
            bail!("camera: the eye {:?} is at the look-at point", cam.eye);
        };
        let left = up.cross(fwd);
        if left.length() <= 1e-9 * up.length() || !left.length().is_finite() {
            bail!("camera: the up vector {:?} is zero or parallel to the view direction", cam.up);
        }
        let left = left.normalize();
        let axes = [left, fwd.cross(left), fwd];
        let (perspective, width) = match cam.projection {
            Projection::Ortho { width } if width > 0.0 && width.is_finite() => (false, width),
            Projection::Ortho { width } => bail!("camera: the orthographic width {width} must be positive"),
            Projection::Perspective { fov_deg } if fov_deg > 0.0 && fov_deg < 180.0 => {
                (true, 2.0 * (fov_deg.to_radians() / 2.0).tan())
            }
            Projection::Perspective { fov_deg } => bail!("camera: the field of view {fov_deg}° is outside (0, 180)"),
        };
        let (near, far) = depth_range(cam, eye, fwd, perspective, n, points)?;
        Ok(View { eye, axes, perspective, width, near, far })
    }

    /// View-space coordinates of a world point.
    pub fn to_view(&self, p: [f64; 3]) -> [f64; 3] {
        let d = Vector::from(p) - self.eye;
        self.axes.map(|a| a.dot(d))
    }

    /// World point of view-space coordinates.
    pub fn from_view(&self, v: [f64; 3]) -> [f64; 3] {
        (self.eye + self.axes[0] * v[0] + self.axes[1] * v[1] + self.axes[2] * v[2]).to_array()
    }

    /// Screen coordinates of a view-space point (depth > 0 for perspective).
    pub fn view_to_screen(&self, v: [f64; 3]) -> [f64; 3] {
        let (near, far) = (self.near, self.far);
        if self.perspective {
            let k = self.width * v[2];
            [v[0] / k + 0.5, v[1] / k + 0.5, far * (v[2] - near) / (v[2] * (far - near))]
        } else {
            [v[0] / self.width + 0.5, v[1] / self.width + 0.5, (v[2] - near) / (far - near)]
        }
    }

    /// View-space point of screen coordinates (the inverse of [`View::view_to_screen`]).
    pub fn screen_to_view(&self, s: [f64; 3]) -> [f64; 3] {
        let (near, far) = (self.near, self.far);
        let z = if self.perspective { near * far / (far - s[2] * (far - near)) } else { near + s[2] * (far - near) };
        let k = if self.perspective { self.width * z } else { self.width };
        [(s[0] - 0.5) * k, (s[1] - 0.5) * k, z]
    }

    /// Screen coordinates of a world point.
    pub fn to_screen(&self, p: [f64; 3]) -> [f64; 3] {
        self.view_to_screen(self.to_view(p))
    }

    /// The primary ray of screen point (s_x, s_y): its world origin (on the near plane) and
    /// unit direction.
    pub fn ray(&self, sx: f64, sy: f64) -> (Vector, Vector) {
        let o = Vector::from(self.from_view(self.screen_to_view([sx, sy, 0.0])));
        let dir = if self.perspective { (o - self.eye).normalize() } else { self.axes[2] };
        (o, dir)
    }

    /// What a cell of an `n`-grid needs to shade in view space.
    pub fn cell_view(&self, n: u32) -> cell_core::shade::CameraView {
        cell_core::shade::CameraView {
            n: n as f32,
            perspective: self.perspective,
            width: self.width as f32,
            near: self.near as f32,
            far: self.far as f32,
        }
    }
}

/// Voxels of depth left empty before and behind the scene by the default near and far planes:
/// surfaces in the grid's first or last layers would be lit by beams that leave the grid.
pub const DEPTH_MARGIN_VOXELS: f64 = 2.0;

/// Near and far: the given ones, else the depths that put the points' depth range (lo ..= hi)
/// at s_z = m ..= 1 − m with m = [`DEPTH_MARGIN_VOXELS`]/n. Perspective: s = A − B/z with
/// A = far/(far − near) and B = A·near, so B = (1 − 2m)/(1/lo − 1/hi), A = m + B/lo,
/// near = B/A, far = B/(A − 1) (a finite far needs A > 1: a scene not too deep for its
/// distance to the eye).
fn depth_range(
    cam: &Camera,
    eye: Vector,
    fwd: Vector,
    perspective: bool,
    n: u32,
    points: impl Iterator<Item = [f64; 3]>,
) -> Result<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        let z = (Vector::from(p) - eye).dot(fwd);
        lo = lo.min(z);
        hi = hi.max(z);
    }
    if let (Some(near), Some(far)) = (cam.near, cam.far) {
        return checked_depths(near, far, perspective);
    }
    if !lo.is_finite() || !hi.is_finite() {
        bail!("camera: the scene has no finite vertex");
    }
    if perspective && hi <= 0.0 && cam.far.is_none() {
        bail!("camera: the whole scene is behind the eye (depths {lo:.4} ..= {hi:.4})");
    }
    if perspective && lo <= 0.0 && cam.near.is_none() {
        bail!("camera: the scene reaches behind the eye (nearest depth {lo:.4}): move the eye back or give --near");
    }
    let m = DEPTH_MARGIN_VOXELS / n as f64;
    let hi = hi.max(lo * (1.0 + 1e-9) + 1e-12);
    let (near, far) = if perspective {
        let b = (1.0 - 2.0 * m) / (1.0 / lo - 1.0 / hi);
        let a = m + b / lo;
        (b / a, if a > 1.0 + 1e-12 { b / (a - 1.0) } else { f64::INFINITY })
    } else {
        let k = (hi - lo) / (1.0 - 2.0 * m);
        (lo - m * k, hi + m * k)
    };
    checked_depths(cam.near.unwrap_or(near), cam.far.unwrap_or(far), perspective)
}

fn checked_depths(near: f64, far: f64, perspective: bool) -> Result<(f64, f64)> {
    if !(near.is_finite() && far.is_finite() && near < far) {
        bail!("camera: near {near} must be below far {far}, both finite (give --near/--far for a very deep scene)");
    }
    if perspective && near <= 0.0 {
        bail!("camera: a perspective near plane must be in front of the eye (near = {near})");
    }
    Ok((near, far))
}

/// A scene seen through a camera: the view, and the world positions the screen-space mesh
/// came from (the reference renders those).
#[derive(Clone, Debug, PartialEq)]
pub struct Screen {
    /// The resolved camera.
    pub view: View,
    /// The mesh's vertex positions in world space.
    pub world: Vec<[f64; 3]>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn persp(fov: f64) -> Camera {
        Camera {
            eye: [1.0, 2.0, -10.0],
            look_at: [1.0, 2.0, 0.0],
            up: [0.0, 1.0, 0.0],
            projection: Projection::Perspective { fov_deg: fov },
            near: Some(5.0),
            far: Some(20.0),
        }
    }

    #[test]
    fn screen_round_trips_and_corners() {
        for cam in [persp(40.0), Camera { projection: Projection::Ortho { width: 6.0 }, ..persp(40.0) }] {
            let v = View::new(&cam, 64, std::iter::empty()).unwrap();
            for p in [[1.0, 2.0, 0.0], [3.5, -1.0, 7.0], [0.2, 2.2, -4.9]] {
                let back = v.from_view(v.screen_to_view(v.to_screen(p)));
                assert!((0..3).all(|i| (back[i] - p[i]).abs() < 1e-9), "{p:?} → {back:?}");
            }
            // Near and far planes map to s_z = 0 and 1; the look-at axis to the image centre.
            let s = v.to_screen([1.0, 2.0, -5.0]);
            assert!(s[0] == 0.5 && s[1] == 0.5 && s[2].abs() < 1e-12, "{s:?}");
            assert!((v.to_screen([1.0, 2.0, 10.0])[2] - 1.0).abs() < 1e-12);
        }
        // Perspective: the edge of the field of view at depth 10 is at s_x = 0 or 1; +x world
        // (the image's left, x of view space) is s_x > ½.
        let v = View::new(&persp(90.0), 64, std::iter::empty()).unwrap();
        let s = v.to_screen([11.0, 2.0, 0.0]);
        assert!((s[0] - 1.0).abs() < 1e-12 && (s[1] - 0.5).abs() < 1e-12, "{s:?}");
    }

    #[test]
    fn bad_cameras_are_errors() {
        let at_eye = Camera { look_at: [1.0, 2.0, -10.0], ..persp(40.0) };
        let up_parallel = Camera { up: [0.0, 0.0, 3.0], ..persp(40.0) };
        let near_far = Camera { near: Some(20.0), far: Some(5.0), ..persp(40.0) };
        let nan = Camera { eye: [f64::NAN, 0.0, 0.0], ..persp(40.0) };
        for (cam, what) in [
            (at_eye, "at the look-at"),
            (up_parallel, "parallel"),
            (persp(0.0), "field of view"),
            (persp(180.0), "field of view"),
            (near_far, "below far"),
            (nan, "not finite"),
        ] {
            let e = View::new(&cam, 64, std::iter::empty()).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        }
        let behind = Camera { near: None, far: None, ..persp(40.0) };
        let e = View::new(&behind, 64, [[0.0, 0.0, -20.0], [1.0, 1.0, -30.0]].into_iter()).unwrap_err().to_string();
        assert!(e.contains("behind the eye"), "{e}");
    }
}
