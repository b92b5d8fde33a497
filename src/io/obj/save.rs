//! Scenes saved as OBJ + MTL (`radiosity generate`), through the one OBJ writer.

use std::path::Path;

use crate::scene::Scene;
use crate::{Error, Result};

/// Write `scene` as an OBJ file at `path` plus its MTL beside it (same name, `.mtl`), both
/// atomically: `Kd` = ρ, `Ke` = Le, faces in the scene's winding. Used by
/// `radiosity generate` to hand the procedural verification scenes to users and other tools.
pub fn save(scene: &Scene, path: &Path) -> Result<()> {
    use std::fmt::Write as _;
    let mtl_path = path.with_extension("mtl");
    let mtl_name = mtl_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut mtl = String::from(
        "# written by radiosity: Kd = diffuse reflectance, Ke = emitted radiance (W sr^-1 m^-2)\n",
    );
    for m in &scene.materials {
        let [r, g, b] = m.reflectance;
        let [er, eg, eb] = m.emission;
        let _ = writeln!(
            mtl,
            "\nnewmtl {}\nKd {r} {g} {b}\nKe {er} {eg} {eb}",
            m.name
        );
    }
    let comments = [format!(
        "written by radiosity: {} vertices, {} triangles; fronts counter-clockwise",
        scene.positions.len(),
        scene.triangles.len()
    )];
    let triangles: Vec<[u32; 3]> = scene.triangles.iter().map(|t| t.vertices).collect();
    let of_triangle: Vec<u32> = scene.triangles.iter().map(|t| t.material).collect();
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    let mut obj = Vec::new();
    super::write_obj(
        &mut obj,
        &comments,
        Some(&mtl_name),
        scene.positions.len(),
        |w, i| {
            let p = scene.positions[i];
            std::io::Write::write_all(w, format!("{} {} {}", p.x, p.y, p.z).as_bytes())
        },
        &triangles,
        Some(super::Groups {
            of_triangle: &of_triangle,
            names: &names,
        }),
    )
    .map_err(|e| Error::io(path, e))?;
    crate::io::write_atomic(&mtl_path, mtl.as_bytes())?;
    crate::io::write_atomic(path, &obj)
}
