//! Mitsuba XML scenes (`radiosity::io::mitsuba`) through the whole pipeline: a closed room
//! read from XML bakes to its closed form, and the shipped example loads as it says. What
//! each element maps to is unit-tested beside the reader.

use radiosity::form_factor::Estimator;
use radiosity::scene::Scene;
use radiosity::solve::Method;

use crate::support::{assert_rel, meshes, run, settings, temp_dir};

#[test]
fn closed_cube_room_from_xml_bakes_to_le_over_one_minus_rho() {
    // A cube turned inside out (flip_normals: every face looks in), ρ = 0.5 and Le = 1 on
    // every face: a closed enclosure of uniform Le and ρ has L = Le / (1 − ρ) = 2 everywhere.
    let dir = temp_dir("mitsuba-furnace");
    let path = dir.join("room.xml");
    std::fs::write(
        &path,
        r#"<scene version="3.0.0">
             <default name="rho" value="0.5"/>
             <bsdf type="diffuse" id="grey"><float name="reflectance" value="$rho"/></bsdf>
             <shape type="cube">
               <boolean name="flip_normals" value="true"/>
               <transform name="to_world"><scale value="2"/><translate value="1 2 3"/></transform>
               <ref id="grey"/>
               <emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter>
             </shape>
           </scene>"#,
    )
    .unwrap();
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.triangles.len(), 12);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let out = run(
        &scene,
        &settings(1.0, Estimator::Contour, 3, Method::GaussSeidel, 1),
    );
    assert!(
        out.solution.radiance.len() > 12,
        "the faces are cut into patches"
    );
    for (i, l) in out.solution.radiance.iter().enumerate() {
        for (c, &v) in l.iter().enumerate() {
            assert_rel(&format!("patch {i} channel {c}"), v, 2.0, 1e-3);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shipped_mitsuba_box_loads_with_its_light_camera_and_colours() {
    let scene = Scene::load(&meshes().join("mitsuba_box.xml")).unwrap();
    // Six rectangles (five walls and the light) and a cube.
    assert_eq!(scene.triangles.len(), 6 * 2 + 12);
    assert!(scene.has_emitters() && scene.camera.is_some());
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    for name in ["white", "red", "green"] {
        assert!(names.contains(&name), "{names:?}");
    }
    // Only the integrator is not read.
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("<integrator> 'path'"));
}
