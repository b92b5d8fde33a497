//! Unit tests of the hierarchical solver.

use super::*;
use crate::mesh;
use crate::validation::{closed_forms, scenes};

#[test]
fn debug_plates() {
    let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
    let roots = mesh::subdivide(&scene, 10.0, 30.0).unwrap();
    let s = Settings::default();
    let mut h = Hierarchy::new(&roots, &s, 1);
    h.start();
    for pass in 0..6 {
        let changed = h.refine_pass();
        h.sweep();
        let mut sum = 0.0;
        for (e, el) in h.tree.elements.iter().enumerate() {
            if el.first_child == tree::NO_CHILD && roots.material[el.root as usize] == 1 {
                sum += el.area * h.elem_l[e][0];
            }
        }
        eprintln!("pass {pass} changed {changed} links {} F {}", h.links.len(), sum / 0.5);
        for l in h.links.iter().take(8) {
            eprintln!("  {:?}", l);
        }
    }
    let _ = closed_forms::parallel_rectangles(1.0, 1.0, 1.0);
}

#[test]
#[ignore]
fn debug_cornell() {
    use crate::pipeline;
    let scene = crate::scene::Scene::load(std::path::Path::new("meshes/cornell_box.obj")).unwrap();
    let reference = crate::validation::path_tracer::read_reference(std::path::Path::new("docs/bench/cornell_reference.csv")).unwrap();
    for eps in [1e-4, 1e-5] {
        let mut s = pipeline::Settings::default();
        s.method = pipeline::Method::Hierarchical;
        s.hierarchical.epsilon = eps;
        s.hierarchical.min_area = 1e-6;
        let out = pipeline::solve_scene(&scene, &s).unwrap();
        let got = crate::validation::path_tracer::solution_means(&scene, &out.patches, &out.solution.radiance, &out.visible_fraction);
        eprintln!("eps {eps}");
        for (k, (g, r)) in got.iter().zip(&reference).enumerate() {
            eprintln!("  surface {k}: got {:.4?} ref {:.4?} rel {:.3}", g, r, (g[0]-r[0])/r[0].max(1e-9));
        }
    }
}

#[test]
#[ignore]
fn debug_row_sums() {
    let mut b = crate::scene::SceneBuilder::new();
    let m = b.material("furnace", [0.5; 3], [1.0; 3]);
    scenes::add_box(&mut b, glam::DVec3::ZERO, glam::DVec3::ONE, true, m);
    let scene = b.build().unwrap();
    let roots = mesh::subdivide(&scene, 10.0, 30.0).unwrap();
    for eps in [1e-2, 1e-3, 1e-4] {
        for rays in [3, 4, 6] {
        let s = Settings { epsilon: eps, min_area: 1e-6, rays, ..Settings::default() };
        let mut h = Hierarchy::new(&roots, &s, 1);
        h.start();
        let mut passes = 0;
        while h.refine_pass() && passes < 60 {
            h.sweep();
            h.sweep();
            passes += 1;
        }
        let rs = h.row_sums();
        let (mut num, mut den, mut lo, mut hi) = (0.0, 0.0, f64::MAX, 0.0f64);
        let (mut cl, mut el) = (0, 0);
        for l in &h.links { if l.receiver.as_cluster().is_some() || l.source.as_cluster().is_some() { cl += 1 } else { el += 1 } }
        for (e, x) in h.tree.elements.iter().enumerate() {
            if x.first_child == tree::NO_CHILD {
                num += x.area * rs[e];
                den += x.area;
                lo = lo.min(rs[e]);
                hi = hi.max(rs[e]);
            }
        }
        eprintln!("rays {rays} eps {eps}: links {} (cluster {cl}, element {el}) mean row sum {:.4} min {lo:.3} max {hi:.3}", h.links.len(), num / den);
        }
    }
}

#[test]
#[ignore]
fn debug_compare() {
    use crate::pipeline;
    use glam::DVec3;
    for with_box in [false, true] {
        let mut b = crate::scene::SceneBuilder::new();
        let w = b.material("wall", [0.7; 3], [0.0; 3]);
        let l = b.material("light", [0.0; 3], [10.0; 3]);
        let faces = scenes::box_faces(DVec3::ZERO, DVec3::ONE);
        for (k, mut q) in faces.into_iter().enumerate() {
            if k == 2 { continue; } // open at y = 0
            q.reverse();
            b.quad(q, w);
        }
        b.quad([DVec3::new(0.4, 0.4, 0.99), DVec3::new(0.4, 0.6, 0.99), DVec3::new(0.6, 0.6, 0.99), DVec3::new(0.6, 0.4, 0.99)], l);
        if with_box {
            scenes::add_box(&mut b, DVec3::new(0.3, 0.3, 0.0), DVec3::new(0.6, 0.6, 0.4), false, w);
        }
        let scene = b.build().unwrap();
        let mut sm = pipeline::Settings::default();
        sm.max_edge = Some(0.03);
        sm.refine_rounds = 0;
        let m = pipeline::solve_scene(&scene, &sm).unwrap();
        let mut sh = pipeline::Settings::default();
        sh.method = pipeline::Method::Hierarchical;
        sh.hierarchical.epsilon = 1e-5;
        sh.hierarchical.min_area = 1e-6;
        let h = pipeline::solve_scene(&scene, &sh).unwrap();
        let mm = crate::validation::path_tracer::solution_means(&scene, &m.patches, &m.solution.radiance, &m.visible_fraction);
        let hm = crate::validation::path_tracer::solution_means(&scene, &h.patches, &h.solution.radiance, &h.visible_fraction);
        eprintln!("box {with_box}: {} vs {} patches", m.patches.len(), h.patches.len());
        for (k, (a, b)) in mm.iter().zip(&hm).enumerate() {
            eprintln!("  surface {k}: matrix {:.5} hier {:.5} rel {:.4}", a[0], b[0], (b[0] - a[0]) / a[0].max(1e-12));
        }
    }
}
