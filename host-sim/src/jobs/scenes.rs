//! The scene utilities: list the built-in scenes (`scenes`), subdivide a mesh (`subdivide`).

use std::path::PathBuf;

use anyhow::Result;

use crate::report::files::create;
use crate::scene::{self, meshops};

/// Print the built-in scenes, one a line: name and description.
pub fn list() {
    for (name, what) in scene::BUILTINS {
        println!("{name:13} {what}");
    }
}

/// What the `subdivide` job reads and writes.
#[derive(Clone, Debug)]
pub struct SubdivideOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// Triangle count to reach.
    pub target: usize,
    /// Output .obj file.
    pub out: PathBuf,
}

/// Subdivide the mesh (1 → 4 midpoint splits) to about the target triangle count and write it.
pub fn subdivide(o: &SubdivideOptions) -> Result<()> {
    let mesh = scene::load(&o.scene)?;
    let sub = meshops::subdivide_to(&mesh, o.target);
    meshops::write_obj(&sub, create(&o.out)?)?;
    eprintln!("{}: {} → {} triangles, written to {}", mesh.name, mesh.faces.len(), sub.faces.len(), o.out.display());
    Ok(())
}
