//! STUB
use glam::DVec3;
pub const NONE: u32 = u32::MAX;
pub struct Visibility {
    tris: Vec<[DVec3; 3]>,
}
impl Visibility {
    pub fn build(triangles: &[[DVec3; 3]]) -> Visibility {
        Visibility {
            tris: triangles.to_vec(),
        }
    }
    pub fn occluded(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        let d = q - p;
        for (i, t) in self.tris.iter().enumerate() {
            if ignore.contains(&(i as u32)) {
                continue;
            }
            let e1 = t[1] - t[0];
            let e2 = t[2] - t[0];
            let h = d.cross(e2);
            let a = e1.dot(h);
            if a.abs() < 1e-300 {
                continue;
            }
            let f = 1.0 / a;
            let s = p - t[0];
            let u = f * s.dot(h);
            if !(0.0..=1.0).contains(&u) {
                continue;
            }
            let qq = s.cross(e1);
            let v = f * d.dot(qq);
            if v < 0.0 || u + v > 1.0 {
                continue;
            }
            let tt = f * e2.dot(qq);
            if tt > 1e-6 && tt < 1.0 - 1e-6 {
                return true;
            }
        }
        false
    }
}
