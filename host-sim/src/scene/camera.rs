//! The geometry stage (thesis §1.3): a camera, and the transform that delivers the scene to the
//! grid in screen space.
//!
//! The machine only ever looks along its own +z. A [`Camera`] (eye, look-at point, up, and an
//! orthographic width or a perspective field of view, near and far) becomes a [`View`], and
//! [`View::to_screen`] maps world space onto the unit screen cube: s_x, s_y ∈ 0 ..= 1 across the
//! image, s_z ∈ 0 ..= 1 from the near plane to the far plane; the grid's voxel (x, y, z) covers
//! s ∈ [v/n, (v + 1)/n). View space has the eye at the origin, z along the view direction, y up
//! and x toward the image's *left* (up × forward): with the image writer's mirrored x
//! ([`crate::machine::shading::pixels`]) a right-handed camera shows what it sees, and the map from world
//! to view space is a rotation (no winding flips).
//!
//! * **Orthographic**: `s_x = x/W + ½`, `s_y = y/W + ½`, `s_z = (z − near)/(far − near)`.
//! * **Perspective** (fov φ, w = 2·tan(φ/2)): `s_x = x/(w·z) + ½`, `s_y = y/(w·z) + ½`,
//!   `s_z = far·(z − near)/(z·(far − near))`. A projective map: planes stay planes and lines
//!   stay lines, so facets voxelize and beams travel in screen space unchanged, and a beam's
//!   straight line is a straight line in the world — shadows stay exact. Depth is non-linear:
//!   a voxel at view depth z spans `z²·(far − near)/(n·near·far)` of depth, finest at the near
//!   plane (at the far plane `far/near` times the near plane's).
//!
//! Angles do not survive the perspective map, so cells shade in view space
//! ([`cell_core::shade::Eye::Camera`]): the host gives each facet its view-space normal and
//! the lights their view-space positions, and the cell maps its visible point back.
//!
//! Near and far default to the scene's depth range and its lights', with
//! [`DEPTH_MARGIN_VOXELS`] of empty depth before and behind; a facet that crosses the near plane, or a scene entirely behind the eye or outside the
//! frustum, is an error (no clipping).

use std::sync::Arc;

use anyhow::{bail, Result};

use super::mesh::Mesh;
pub use super::view::{Camera, Projection, Screen, View, DEPTH_MARGIN_VOXELS};

/// Which view a job loads a scene with.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum ViewChoice {
    /// The scene's own camera if it has one ([`scene_camera`]: the Cornell box), else fitted.
    #[default]
    Auto,
    /// No camera: the scene fitted into the grid, seen along +z (every figure before cameras).
    Fitted,
    /// The scene's own camera ([`scene_camera`]; an error for a scene that has none).
    Scene,
    /// A camera the user gave.
    Custom(Camera),
}

/// The camera a built-in scene is published with, if any.
pub fn scene_camera(name: &str) -> Option<Camera> {
    matches!(name, "cornell" | "cornell-mirror" | "cornell-glass").then_some(Camera::CORNELL)
}

/// `mesh` as `choice` sees it: unchanged (fitted), or in screen space through a camera.
pub fn apply(mesh: Mesh, choice: &ViewChoice, n: u32) -> Result<Mesh> {
    match choice {
        ViewChoice::Auto => match scene_camera(&mesh.name) {
            Some(cam) => to_screen(mesh, &cam, n),
            None => Ok(mesh),
        },
        ViewChoice::Fitted => Ok(mesh),
        ViewChoice::Scene => match scene_camera(&mesh.name) {
            Some(cam) => to_screen(mesh, &cam, n),
            None => bail!("{}: the scene has no camera of its own: give --eye and --look-at", mesh.name),
        },
        ViewChoice::Custom(cam) => to_screen(mesh, cam, n),
    }
}

/// The mesh as the geometry stage delivers it: positions in screen space (the unit cube),
/// [`Mesh::screen`] set. Errors: a bad camera, a used vertex outside the near–far range or
/// behind the eye, no face inside the view.
pub fn to_screen(mesh: Mesh, cam: &Camera, n: u32) -> Result<Mesh> {
    if mesh.screen.is_some() {
        bail!("{}: the scene is already in screen space", mesh.name);
    }
    // The depth range holds the used vertices and the scene's own lights (a light is a source
    // in the grid: it must lie in the screen cube too).
    let lights = mesh.lights.iter().filter_map(|l| match l.at {
        super::mesh::LightAt::World(w) => Some(w),
        super::mesh::LightAt::Grid(_) => None,
    });
    let used = mesh.faces.iter().flat_map(|f| f.verts.iter().map(|&v| mesh.positions[v as usize]));
    let view = View::new(cam, n, used.chain(lights))?;
    let mut inside_any = false;
    for (fi, f) in mesh.faces.iter().enumerate() {
        let mut inside = true;
        for &v in &f.verts {
            let z = view.to_view(mesh.positions[v as usize])[2];
            if z < view.near || z > view.far {
                bail!(
                    "{}: face {} has a vertex at depth {z:.4}, outside near {:.4} ..= far {:.4} (no clipping: \
                     move the eye or give --near/--far)",
                    mesh.name,
                    fi + 1,
                    view.near,
                    view.far
                );
            }
            let s = view.to_screen(mesh.positions[v as usize]);
            inside &= s[0] >= 0.0 && s[0] <= 1.0 && s[1] >= 0.0 && s[1] <= 1.0;
        }
        inside_any |= inside;
    }
    if !inside_any {
        bail!("{}: no face lies entirely inside the camera's view", mesh.name);
    }
    let positions = mesh.positions.iter().map(|&p| view.to_screen(p)).collect();
    let world = mesh.positions.clone();
    Ok(Mesh { positions, screen: Some(Arc::new(Screen { view, world })), ..mesh })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default view is the scene's own camera where it has one, the fitted view elsewhere;
    /// `fitted` never uses a camera and `scene` needs one.
    #[test]
    fn the_default_view_is_the_scenes_camera() {
        let load = |s: &str| crate::scene::load(s).unwrap();
        let cornell = apply(load("cornell"), &ViewChoice::default(), 64).unwrap();
        let screen = cornell.screen.as_ref().expect("the Cornell box is seen through its camera");
        assert_eq!(screen.view.eye.to_array(), Camera::CORNELL.eye);
        assert!(screen.view.perspective);
        assert!(apply(load("cornell"), &ViewChoice::Fitted, 64).unwrap().screen.is_none());
        let facet = load("facet");
        assert_eq!(
            apply(facet.clone(), &ViewChoice::Auto, 64).unwrap().positions,
            facet.positions,
            "no camera: fitted"
        );
        assert!(apply(facet, &ViewChoice::Scene, 64).is_err());
    }
}
