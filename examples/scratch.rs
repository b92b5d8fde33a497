use radiosity::{form_factor, pipeline, reference, scenes, solve};
fn main() {
    let level: u32 = std::env::args().nth(1).unwrap().parse().unwrap();
    let samples: u32 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(3);
    let rho = 0.5;
    let scene = scenes::integrating_sphere(1.0, level, 30.0, rho, [1.0; 3]).unwrap();
    for bounces in [Some(1), None] {
        let (method, n) = match bounces {
            Some(n) => (solve::Method::Neumann, n),
            None => (solve::Method::GaussSeidel, 40),
        };
        let s = pipeline::Settings {
            max_edge: Some(10.0),
            form_factors: form_factor::Settings {
                samples,
                ..Default::default()
            },
            solver: solve::Settings {
                method,
                tolerance: 1e-9,
                max_iterations: 10000,
                bounces: n,
            },
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let out = pipeline::solve_scene(&scene, &s).unwrap();
        let p = &out.patches;
        let total = p.total_area();
        let mean_le: f64 = (0..p.len())
            .map(|i| p.area[i] * p.emission[i][0])
            .sum::<f64>()
            / total;
        let expected = reference::sphere_wall_radiance(rho, mean_le, bounces);
        let walls: Vec<usize> = (0..p.len()).filter(|&i| p.emission[i][0] == 0.0).collect();
        let wa: f64 = walls.iter().map(|&i| p.area[i]).sum();
        let err = walls
            .iter()
            .map(|&i| p.area[i] * (out.solution.radiance[i][0] - expected).abs() / expected)
            .sum::<f64>()
            / wa;
        let maxe = walls
            .iter()
            .map(|&i| (out.solution.radiance[i][0] - expected).abs() / expected)
            .fold(0.0, f64::max);
        let meanv = walls
            .iter()
            .map(|&i| p.area[i] * out.solution.radiance[i][0])
            .sum::<f64>()
            / wa;
        println!("level {level} n {} bounces {:?}: mean rel err {err:.3e} max {maxe:.3e} mean-of-L err {:.3e} t {:.2}s", p.len(), bounces, (meanv-expected).abs()/expected, t.elapsed().as_secs_f64());
    }
}
