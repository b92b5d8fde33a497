use super::*;
use crate::test_support::TestDir;

/// Loads `xml` written as `scene.xml` in `dir`.
fn load_in(dir: &TestDir, xml: &str) -> Result<Scene> {
    load(&dir.write("scene.xml", xml))
}

fn load_xml(xml: &str) -> Result<Scene> {
    load_in(&TestDir::new("mitsuba"), xml)
}

fn normal(s: &Scene, t: usize) -> DVec3 {
    let [a, b, c] = s.triangles[t].vertices.map(|v| s.positions[v as usize]);
    (b - a).cross(c - a)
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-9
}

#[test]
fn defaults_are_substituted_and_a_missing_one_is_named() {
    let doc = Document::parse(
        r#"<scene version="3.0.0"><default name="rho" value="0.25"/>
           <default name="side" value="2"/></scene>"#,
    )
    .unwrap();
    let mut r = Reader::new(Path::new("x.xml"), &doc);
    r.index(doc.root_element()).unwrap();
    let node = doc.root_element();
    assert_eq!(
        r.substitute(node, "$rho, $rho $side").unwrap(),
        "0.25, 0.25 2"
    );
    assert_eq!(r.substitute(node, "plain").unwrap(), "plain");
    let e = r.substitute(node, "$spp").unwrap_err().to_string();
    assert!(e.contains("x.xml:1") && e.contains("$spp"), "{e}");

    let s = load_xml(
        r#"<scene version="3.0.0">
             <default name="rho" value="0.25"/>
             <shape type="rectangle"><bsdf type="diffuse">
               <rgb name="reflectance" value="$rho"/></bsdf></shape>
           </scene>"#,
    )
    .unwrap();
    assert_eq!(s.materials[0].reflectance, [0.25; 3]);
    let e = load_xml(
        r#"<scene version="3.0.0">
             <shape type="rectangle"><bsdf type="diffuse">
               <rgb name="reflectance" value="$albedo"/></bsdf></shape>
           </scene>"#,
    )
    .unwrap_err();
    assert!(matches!(e, Error::Parse { line: 3, .. }), "{e:?}");
    assert!(e.to_string().contains("$albedo"), "{e}");
}

#[test]
fn transform_steps_compose_in_document_order() {
    // Translate by (1, 0, 0), then rotate 90° about +z: (1, 0, 0) → (2, 0, 0) → (0, 2, 0).
    let doc = Document::parse(
        r#"<transform name="to_world">
             <translate x="1"/>
             <rotate axis="0 0 1" angle="90"/>
           </transform>"#,
    )
    .unwrap();
    let mut r = Reader::new(Path::new("x.xml"), &doc);
    let m = r.transform(doc.root_element()).unwrap();
    assert!(close(
        m.transform_point3(DVec3::X),
        DVec3::new(0.0, 2.0, 0.0)
    ));
    // The other order: rotate first, then translate: (1, 0, 0) → (0, 1, 0) → (1, 1, 0).
    let doc = Document::parse(
        r#"<transform name="to_world"><rotate z="1" angle="90"/>
           <translate value="1 0 0"/><scale value="2"/></transform>"#,
    )
    .unwrap();
    let mut r = Reader::new(Path::new("x.xml"), &doc);
    let m = r.transform(doc.root_element()).unwrap();
    assert!(close(
        m.transform_point3(DVec3::X),
        DVec3::new(2.0, 2.0, 0.0)
    ));
    // A row-major matrix: the translation is the last column.
    let doc = Document::parse(
        r#"<transform name="to_world">
             <matrix value="1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1"/></transform>"#,
    )
    .unwrap();
    let mut r = Reader::new(Path::new("x.xml"), &doc);
    let m = r.transform(doc.root_element()).unwrap();
    assert!(close(
        m.transform_point3(DVec3::ZERO),
        DVec3::new(5.0, 6.0, 7.0)
    ));
}

#[test]
fn rectangle_with_to_world_has_its_corners_and_facing() {
    // Scaled by (2, 3, 1), turned 90° about +x (its front +z becomes −y), moved up by 5.
    let s = load_xml(
        r#"<scene version="0.6.0"><shape type="rectangle">
             <transform name="toWorld"><scale x="2" y="3"/><rotate x="1" angle="90"/>
               <translate y="5"/></transform>
           </shape></scene>"#,
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 2);
    let mut corners: Vec<[i64; 3]> = s
        .positions
        .iter()
        .map(|p| p.to_array().map(|c| c.round() as i64))
        .collect();
    corners.sort();
    assert_eq!(
        corners,
        [[-2, 5, -3], [-2, 5, 3], [2, 5, -3], [2, 5, 3]],
        "{:?}",
        s.positions
    );
    for t in 0..2 {
        assert!(
            close(normal(&s, t).normalize(), -DVec3::Y),
            "{}",
            normal(&s, t)
        );
    }
    // flip_normals turns it over.
    let s = load_xml(
        r#"<scene version="3.0.0"><shape type="rectangle">
             <boolean name="flip_normals" value="true"/></shape></scene>"#,
    )
    .unwrap();
    assert!(close(normal(&s, 0).normalize(), -DVec3::Z));
}

/// Six times the signed volume the triangles enclose (positive when fronts face out).
fn signed_volume(s: &Scene) -> f64 {
    s.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.vertices.map(|v| s.positions[v as usize]);
            a.dot(b.cross(c))
        })
        .sum()
}

#[test]
fn cube_is_closed_with_outward_fronts() {
    let s = load_xml(r#"<scene version="3.0.0"><shape type="cube"/></scene>"#).unwrap();
    assert_eq!((s.positions.len(), s.triangles.len()), (8, 12));
    // Closed: every edge is used once in each direction.
    let mut edges = std::collections::HashMap::new();
    for t in &s.triangles {
        for k in 0..3 {
            *edges
                .entry((t.vertices[k], t.vertices[(k + 1) % 3]))
                .or_insert(0) += 1;
        }
    }
    assert!(edges
        .keys()
        .all(|&(a, b)| edges[&(a, b)] == 1 && edges.get(&(b, a)) == Some(&1)));
    assert!((signed_volume(&s) / 6.0 - 8.0).abs() < 1e-12);
    // Mirrored by a negative scale, the fronts still face out.
    let s = load_xml(
        r#"<scene version="3.0.0"><shape type="cube">
             <transform name="to_world"><scale value="1 1 -1"/></transform>
           </shape></scene>"#,
    )
    .unwrap();
    assert!(signed_volume(&s) > 0.0);
}

#[test]
fn sphere_area_is_within_its_tessellation_error() {
    let s = load_xml(
        r#"<scene version="3.0.0"><shape type="sphere">
             <point name="center" x="1" y="2" z="3"/><float name="radius" value="2"/>
           </shape></scene>"#,
    )
    .unwrap();
    let area: f64 = (0..s.triangles.len()).map(|t| s.triangle_area(t)).sum();
    let exact = 4.0 * std::f64::consts::PI * 4.0;
    // Inscribed, so smaller; 5120 triangles fall short by about 0.2 %.
    assert!(area < exact && area > exact * 0.995, "{area} vs {exact}");
    let centre = DVec3::new(1.0, 2.0, 3.0);
    assert!(s
        .positions
        .iter()
        .all(|p| ((*p - centre).length() - 2.0).abs() < 1e-9));
    // Fronts face out: the enclosed volume about the centre is positive.
    let outward = (0..s.triangles.len()).all(|t| {
        normal(&s, t).dot(s.positions[s.triangles[t].vertices[0] as usize] - centre) > 0.0
    });
    assert!(outward);
}

#[test]
fn bsdf_references_share_one_material_and_twosided_gives_twins() {
    let s = load_xml(
        r#"<scene version="3.0.0">
             <bsdf type="twosided" id="white"><bsdf type="diffuse">
               <rgb name="reflectance" value="0.8, 0.7, 0.6"/></bsdf></bsdf>
             <bsdf type="diffuse" id="red"><srgb name="reflectance" value="1 0 0"/></bsdf>
             <shape type="rectangle"><ref id="white"/></shape>
             <shape type="rectangle"><ref name="bsdf" id="white"/>
               <transform name="to_world"><translate z="1"/></transform></shape>
             <shape type="rectangle"><ref id="red"/>
               <transform name="to_world"><translate z="2"/></transform></shape>
           </scene>"#,
    )
    .unwrap();
    assert_eq!(s.materials.len(), 2);
    assert_eq!(s.materials[0].name, "white");
    assert_eq!(s.materials[0].reflectance, [0.8, 0.7, 0.6]);
    assert_eq!(s.materials[1].reflectance, [1.0, 0.0, 0.0]);
    // Two rectangles of "white" and their twins; "red" is one-sided.
    assert_eq!(s.triangles.len(), 6 + 4);
    let twinned = (0..s.triangles.len())
        .filter(|&t| s.twin[t] != crate::scene::NO_TWIN)
        .count();
    assert_eq!(twinned, 8);
    assert!(s.triangles[6..].iter().all(|t| t.material == 0));
    s.validate().unwrap();

    let e = load_xml(
        r#"<scene version="3.0.0">
             <shape type="rectangle"><ref id="nothing"/></shape></scene>"#,
    )
    .unwrap_err();
    assert!(matches!(e, Error::Parse { line: 2, .. }), "{e:?}");
    assert!(e.to_string().contains("nothing"), "{e}");
}

#[test]
fn area_emitter_sets_the_emission_and_keeps_the_bsdf() {
    let s = load_xml(
        r#"<scene version="3.0.0">
             <shape type="disk" id="lamp">
               <bsdf type="diffuse"><float name="reflectance" value="0.3"/></bsdf>
               <emitter type="area"><rgb name="radiance" value="4 5 6"/></emitter>
             </shape>
             <shape type="rectangle"><emitter type="area">
               <spectrum name="radiance" value="2"/></emitter></shape>
           </scene>"#,
    )
    .unwrap();
    assert_eq!(s.materials[0].emission, [4.0, 5.0, 6.0]);
    assert_eq!(s.materials[0].reflectance, [0.3; 3]);
    assert!(
        s.materials[0].name.contains("lamp"),
        "{}",
        s.materials[0].name
    );
    assert_eq!(s.materials[1].emission, [2.0; 3]);
    assert_eq!(s.materials[1].reflectance, [0.5; 3]);
    assert_eq!(
        s.triangles.len(),
        shapes::DISK_SEGMENTS + 2,
        "a 64-segment disk and a rectangle"
    );
    assert!(s.has_emitters());
}

#[test]
fn obj_shapes_are_read_relative_to_the_xml_and_a_missing_one_is_an_error() {
    let dir = TestDir::new("mitsuba-obj");
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    dir.write("meshes/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let s = load_in(
        &dir,
        r#"<scene version="3.0.0">
             <shape type="obj"><string name="filename" value="meshes/tri.obj"/>
               <transform name="to_world"><translate z="2"/></transform>
               <bsdf type="diffuse"><rgb name="reflectance" value="0.1"/></bsdf>
             </shape></scene>"#,
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 1);
    assert!(s.positions.iter().all(|p| p.z == 2.0));
    assert_eq!(s.materials[0].reflectance, [0.1; 3]);

    let e = load_in(
        &dir,
        r#"<scene version="3.0.0">

             <shape type="obj"><string name="filename" value="meshes/gone.obj"/></shape>
           </scene>"#,
    )
    .unwrap_err();
    assert!(matches!(e, Error::Parse { line: 3, .. }), "{e:?}");
    let text = e.to_string();
    assert!(
        text.contains("scene.xml:3") && text.contains("gone.obj"),
        "{text}"
    );
}

#[test]
fn malformed_xml_and_bad_numbers_name_file_and_line() {
    let e = load_xml("<scene>\n<shape type=\"cube\">\n</scene>").unwrap_err();
    assert!(matches!(e, Error::Parse { line: 3, .. }), "{e:?}");
    assert!(e.to_string().contains("scene.xml:3"), "{e}");
    let e = load_xml(
        "<scene>\n<shape type=\"cube\"><transform name=\"to_world\">\n\
         <translate x=\"one\"/></transform></shape></scene>",
    )
    .unwrap_err();
    assert!(matches!(e, Error::Parse { line: 3, .. }), "{e:?}");
    assert!(e.to_string().contains("'one'"), "{e}");
}

/// A scene of shapes the reader does not take has no triangles: the error says which
/// elements were passed over, not only that the mesh is empty.
#[test]
fn a_scene_of_unread_shapes_is_an_error_naming_them() {
    let e = load_xml(r#"<scene version="3.0.0"><shape type="teapot"/></scene>"#).unwrap_err();
    assert!(matches!(e, Error::Input { .. }), "{e:?}");
    let text = e.to_string();
    assert!(
        text.contains("the mesh is empty") && text.contains("<shape> 'teapot' ×1"),
        "{text}"
    );
}

#[test]
fn elements_not_read_are_named_in_one_warning() {
    let s = load_xml(
        r#"<scene version="3.0.0">
             <integrator type="path"><integer name="max_depth" value="8"/></integrator>
             <sensor type="perspective">
               <float name="fov" value="45"/>
               <transform name="to_world"><lookat origin="0 0 5" target="0 0 0" up="0 1 0"/>
               </transform>
               <sampler type="independent"/>
               <film type="hdrfilm"><integer name="width" value="400"/>
                 <integer name="height" value="400"/></film>
             </sensor>
             <shape type="cylinder"/>
             <shape type="cylinder"/>
             <shape type="rectangle"/>
           </scene>"#,
    )
    .unwrap();
    let unread: Vec<&String> = s
        .warnings
        .iter()
        .filter(|w| w.starts_with("not read"))
        .collect();
    assert_eq!(unread.len(), 1, "{:?}", s.warnings);
    for part in [
        "<integrator> 'path' ×1",
        "<sampler> 'independent' ×1",
        "<shape> 'cylinder' ×2",
    ] {
        assert!(unread[0].contains(part), "{part}: {}", unread[0]);
    }
    // The camera: a square film, so the vertical field of view is the horizontal one.
    let c = s.camera.unwrap();
    assert!(close(c.eye, DVec3::new(0.0, 0.0, 5.0)) && close(c.target, DVec3::new(0.0, 0.0, 4.0)));
    assert!((c.vfov_degrees - 45.0).abs() < 1e-9);
}

#[test]
fn lights_sky_and_glass_are_read() {
    let s = load_xml(
        r#"<scene version="3.0.0">
             <emitter type="point"><point name="position" x="0" y="3" z="0"/>
               <rgb name="intensity" value="10"/></emitter>
             <emitter type="spot"><rgb name="intensity" value="5"/>
               <float name="cutoff_angle" value="30"/>
               <transform name="to_world"><lookat origin="0 4 0" target="0 0 0" up="0 0 1"/>
               </transform></emitter>
             <emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>
             <emitter type="envmap"><string name="filename" value="sky.exr"/></emitter>
             <shape type="rectangle"><bsdf type="thindielectric" id="pane"/></shape>
             <shape type="disk"><bsdf type="diffuse" id="frame"/></shape>
           </scene>"#,
    )
    .unwrap();
    assert_eq!(s.lights.len(), 2);
    assert_eq!(s.lights[0].intensity, [10.0; 3]);
    let spot = s.lights[1].spot.unwrap();
    assert!(close(spot.direction, -DVec3::Y) && close(s.lights[1].position, 4.0 * DVec3::Y));
    assert_eq!((spot.inner_degrees, spot.outer_degrees), (22.5, 30.0));
    assert_eq!(s.sky, Some([0.2; 3]));
    // The clear pane is left out; the frame's faces stay.
    let pane = s.materials.iter().find(|m| m.name == "pane").unwrap();
    assert_eq!(pane.transmittance, 1.0);
    assert!(s
        .triangles
        .iter()
        .all(|t| s.materials[t.material as usize].name == "frame"));
    assert!(s
        .warnings
        .iter()
        .any(|w| w.contains("left out") && w.contains("pane")));
    assert!(s
        .warnings
        .iter()
        .any(|w| w.contains("sky.exr") && w.contains("--sky")));
    assert!(s
        .warnings
        .iter()
        .any(|w| w.contains("glass") && w.contains("pane")));
}
