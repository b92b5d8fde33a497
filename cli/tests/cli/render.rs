//! `radiosity render` (and `bake --png`): a baked PLY rendered as it is, a scene baked first,
//! the picture options and their errors.

use crate::support::{bake_cornell, cornell, radiosity, stderr, temp_dir};

#[test]
fn render_a_baked_ply_and_a_scene() {
    let dir = temp_dir("render");
    let ply_path = dir.join("c.ply");
    assert!(bake_cornell(&ply_path, &[]).status.success());
    let png_path = dir.join("view.png");
    for extra in [
        &[][..],
        &["--flat"][..],
        &["--false-colour", "--size", "96x64"][..],
    ] {
        let mut args = vec![
            "render",
            ply_path.to_str().unwrap(),
            "-o",
            png_path.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = radiosity(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let img = image::open(&png_path).unwrap().to_rgb8();
        let (w, h) = if extra.contains(&"96x64") {
            (96, 64)
        } else {
            (512, 512)
        };
        assert_eq!(img.dimensions(), (w, h));
        // The default camera looks into the box: most pixels are lit, none of the picture is
        // uniformly black.
        let lit = img.pixels().filter(|p| p.0.iter().any(|&c| c > 20)).count();
        assert!(
            lit > (w * h) as usize / 2,
            "{extra:?}: only {lit} lit pixels"
        );
    }
    // A scene is baked first, with the bake options.
    let cornell = cornell();
    let o = radiosity(&[
        "render",
        &cornell,
        "-o",
        png_path.to_str().unwrap(),
        "--max-edge",
        "150",
        "--size",
        "64",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Bad camera and size are usage errors naming the option; the picture is left as it was.
    let before = std::fs::read(&png_path).unwrap();
    for bad in [["--camera", "1,2,3"], ["--size", "0x5"]] {
        let o = radiosity(&[
            "render",
            ply_path.to_str().unwrap(),
            "-o",
            png_path.to_str().unwrap(),
            bad[0],
            bad[1],
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(bad[0]), "{}", stderr(&o));
    }
    assert_eq!(std::fs::read(&png_path).unwrap(), before);
}
