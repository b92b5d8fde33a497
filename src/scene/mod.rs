//! STUB (replaced by the real module)
use crate::Result;
use glam::DVec3;
use std::path::{Path, PathBuf};
#[derive(Debug, Clone)]
pub struct Material {
    pub name: String,
    pub reflectance: [f64; 3],
    pub emission: [f64; 3],
}
#[derive(Debug, Clone, Copy)]
pub struct SceneTriangle {
    pub vertices: [u32; 3],
    pub material: u32,
}
#[derive(Debug, Clone)]
pub struct Scene {
    pub source: Option<PathBuf>,
    pub positions: Vec<DVec3>,
    pub triangles: Vec<SceneTriangle>,
    pub materials: Vec<Material>,
    pub warnings: Vec<String>,
}
impl Scene {
    pub fn load(_path: &Path) -> Result<Scene> {
        todo!()
    }
    pub fn validate(&self) -> Result<()> {
        Ok(())
    }
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (lo, hi)
    }
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t]
            .vertices
            .map(|v| self.positions[v as usize]);
        0.5 * (b - a).cross(c - a).length()
    }
    pub fn has_emitters(&self) -> bool {
        self.materials
            .iter()
            .any(|m| m.emission.iter().any(|&e| e > 0.0))
    }
}
#[derive(Default)]
pub struct SceneBuilder {
    s: Vec<DVec3>,
    t: Vec<SceneTriangle>,
    m: Vec<Material>,
}
impl SceneBuilder {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn material(&mut self, name: &str, reflectance: [f64; 3], emission: [f64; 3]) -> u32 {
        self.m.push(Material {
            name: name.into(),
            reflectance,
            emission,
        });
        (self.m.len() - 1) as u32
    }
    pub fn vertex(&mut self, p: DVec3) -> u32 {
        if let Some(i) = self.s.iter().position(|q| *q == p) {
            return i as u32;
        }
        self.s.push(p);
        (self.s.len() - 1) as u32
    }
    pub fn triangle(&mut self, v: [u32; 3], material: u32) {
        self.t.push(SceneTriangle {
            vertices: v,
            material,
        });
    }
    pub fn quad(&mut self, c: [DVec3; 4], material: u32) {
        let v = c.map(|p| self.vertex(p));
        self.triangle([v[0], v[1], v[2]], material);
        self.triangle([v[0], v[2], v[3]], material);
    }
    pub fn build(self) -> Result<Scene> {
        Ok(Scene {
            source: None,
            positions: self.s,
            triangles: self.t,
            materials: self.m,
            warnings: vec![],
        })
    }
}
