//! The `reference` section: the path-traced per-surface reference of the Cornell box
//! (docs/bench/cornell_reference.csv).

use super::*;

pub(super) fn reference(args: &Args) -> Result<String> {
    let scene = cornell()?;
    let (labels, count) = path_tracer::surfaces(&scene);
    let paths = if args.quick { 1_000_000 } else { 16_000_000 };
    let t = Instant::now();
    let means = path_tracer::surface_means(
        &scene,
        &labels,
        count,
        &path_tracer::Settings {
            paths_per_surface: paths,
            seed: 1,
        },
    );
    let secs = t.elapsed().as_secs_f64();
    let mut csv = String::from(
        "surface,material,area,visible_fraction,mean_r,mean_g,mean_b,se_r,se_g,se_b,visible_mean_r,visible_mean_g,visible_mean_b\n",
    );
    for (k, m) in means.iter().enumerate() {
        let t = labels
            .iter()
            .position(|&l| l as usize == k)
            .expect("a triangle");
        let material = &scene.materials[scene.triangles[t].material as usize].name;
        writeln!(
            csv,
            "{k},{material},{:.1},{:.5},{:.7e},{:.7e},{:.7e},{:.3e},{:.3e},{:.3e},{:.7e},{:.7e},{:.7e}",
            m.area,
            m.visible_fraction,
            m.mean[0],
            m.mean[1],
            m.mean[2],
            m.std_error[0],
            m.std_error[1],
            m.std_error[2],
            m.visible_mean[0],
            m.visible_mean[1],
            m.visible_mean[2]
        )?;
    }
    let path = radiosity_tools::root().join("docs/bench/cornell_reference.csv");
    std::fs::write(&path, csv)?;
    Ok(format!(
        "Path-traced reference of the Cornell box: {count} surfaces, {paths} paths each, seed 1, \
         {secs:.0} s; written to {}.\n",
        path.display()
    ))
}
