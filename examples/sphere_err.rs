use radiosity::pipeline::{solve_scene, Settings};
use radiosity::{reference, scenes, solve};
fn main() {
    let level: u32 = std::env::args().nth(1).unwrap().parse().unwrap();
    let samples: u32 = std::env::args().nth(2).unwrap().parse().unwrap();
    let scene = scenes::integrating_sphere(1.0, level, 30.0, 0.5, [1.0; 3]).unwrap();
    let mut s = Settings::default();
    s.max_edge = Some(10.0);
    s.form_factors.samples = samples;
    s.solver.method = solve::Method::Neumann;
    s.solver.bounces = 1;
    let t = std::time::Instant::now();
    let out = solve_scene(&scene, &s).unwrap();
    let p = &out.patches;
    let total = p.total_area();
    let mean_le: f64 = (0..p.len())
        .map(|i| p.area[i] * p.emission[i][0])
        .sum::<f64>()
        / total;
    let expected = reference::sphere_wall_radiance(0.5, mean_le, Some(1));
    let walls: Vec<usize> = (0..p.len()).filter(|&i| p.emission[i][0] == 0.0).collect();
    let wa: f64 = walls.iter().map(|&i| p.area[i]).sum();
    let err: f64 = walls
        .iter()
        .map(|&i| p.area[i] * (out.solution.radiance[i][0] - expected).abs() / expected)
        .sum::<f64>()
        / wa;
    let signed: f64 = walls
        .iter()
        .map(|&i| p.area[i] * (out.solution.radiance[i][0] - expected) / expected)
        .sum::<f64>()
        / wa;
    println!("level {level} samples {samples}: patches {} mean|err| {err:.3e} mean err {signed:.3e} {:.2}s", p.len(), t.elapsed().as_secs_f64());
}
