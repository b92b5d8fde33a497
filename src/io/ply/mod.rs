//! PLY 1.0, both ways: scene files read into a [`crate::scene::Scene`] ([`load`], any PLY a
//! modelling tool writes: ASCII or binary little-endian, any scalar types, materials from
//! optional `reflectance_*`/`emission_*` properties), baked meshes written for MeshLab
//! ([`write_to`]) and read back exactly ([`read`]). Both readers parse the header with the
//! one header layer of `header`, so they agree on every header rule (comments, the camera
//! line, a second camera line being an error).

mod baked;
mod header;
mod scene;

pub use baked::{read, write_to};
pub use scene::load;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{sample_mesh, TestDir};
    use crate::Error;

    /// The two readers share one header layer: a baked file with a second camera comment is
    /// refused by both at the same line, and a good one gives both the same camera.
    #[test]
    fn both_readers_apply_the_same_header_rules() {
        let dir = TestDir::new("ply-header");
        let path = dir.path().join("baked.ply");
        let mut mesh = sample_mesh(4, 2);
        mesh.positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        mesh.faces = vec![[0, 1, 2], [1, 3, 2]];
        mesh.camera = Some(crate::scene::Camera::parse("0,0,5,0,0,0,0,1,0,40").unwrap());
        let mut bytes = Vec::new();
        write_to(&mut bytes, &mesh, 1.0, true).unwrap();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read(&path).unwrap().camera, mesh.camera);
        assert_eq!(load(&path).unwrap().camera, mesh.camera);

        let text = String::from_utf8(bytes).unwrap();
        let line = text
            .lines()
            .position(|l| l.starts_with("comment camera"))
            .unwrap()
            + 1;
        let twice = text.replacen(
            "comment camera",
            "comment camera: 1 1 1 0 0 0 0 1 0 30\ncomment camera",
            1,
        );
        std::fs::write(&path, twice).unwrap();
        for e in [read(&path).unwrap_err(), load(&path).unwrap_err()] {
            match e {
                Error::Parse {
                    line: l, message, ..
                } => {
                    assert_eq!(l, line + 1, "{message}");
                    assert!(message.contains("second camera"), "{message}");
                }
                other => panic!("{other:?}"),
            }
        }
    }
    /// A baked file carries the bake's sky for pictures; the scene reader ignores the line,
    /// the read-back refuses a malformed one at its line.
    #[test]
    fn baked_files_carry_the_sky() {
        use crate::scene::{Sky, SkyModel, Up};
        let dir = TestDir::new("ply-sky");
        let path = dir.path().join("baked.ply");
        let mut mesh = sample_mesh(3, 1);
        mesh.positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        mesh.faces = vec![[0, 1, 2]];
        let sky = Sky {
            radiance: [0.1, 1.0 / 3.0, 2.5],
            model: SkyModel::Overcast,
            up: Up::Z,
        };
        mesh.sky = Some(sky);
        for ascii in [true, false] {
            let mut bytes = Vec::new();
            write_to(&mut bytes, &mesh, 1.0, ascii).unwrap();
            std::fs::write(&path, &bytes).unwrap();
            let back = read(&path).unwrap();
            assert_eq!(back.sky, Some(sky));
            assert_eq!(back.into_baked().unwrap().sky, Some(sky));
            assert!(load(&path).is_ok());
        }
        let mut bytes = Vec::new();
        write_to(&mut bytes, &mesh, 1.0, true).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        assert!(text.contains("comment sky: 0.1 0.3333333333333333 2.5 overcast z\n"));
        let line = text
            .lines()
            .position(|l| l.starts_with("comment sky"))
            .unwrap()
            + 1;
        std::fs::write(&path, text.replace("overcast z", "cloudy z")).unwrap();
        match read(&path).unwrap_err() {
            Error::Parse {
                line: l, message, ..
            } => {
                assert_eq!(l, line, "{message}");
                assert!(message.contains("sky model"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        assert!(load(&path).is_ok(), "a scene's comments are its own");
    }
}
