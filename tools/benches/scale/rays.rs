//! The `rays` section: visibility rays per second on the form-factor workload, and the same segments for Embree (tools/embree_rays.py).

use super::*;

/// An occlusion query: two points and the triangles they lie on.
type Segment = (glam::DVec3, glam::DVec3, [u32; 2]);

/// A closed room of 26 × 26 squares per face with ten boxes inside, 10,032 triangles (the
/// scene of `visibility::tests::throughput`), and 1M segments between random surface points.
pub(super) fn ray_scene() -> (Vec<[glam::DVec3; 3]>, Vec<Segment>) {
    use glam::DVec3;
    let mut rng = form_factor::sampling::Rng::new(&[6]);
    let grid_box = |lo: DVec3, hi: DVec3, k: usize| {
        let mut out = Vec::new();
        for face in scenes::box_faces(lo, hi) {
            let [a, b, _, d] = face;
            let (u, v) = ((b - a) / k as f64, (d - a) / k as f64);
            for i in 0..k {
                for j in 0..k {
                    let p = a + u * i as f64 + v * j as f64;
                    out.push([p, p + u, p + u + v]);
                    out.push([p, p + u + v, p + v]);
                }
            }
        }
        out
    };
    let mut tris = grid_box(DVec3::ZERO, DVec3::splat(10.0), 26);
    for _ in 0..10 {
        let lo = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 7.5 + 0.5;
        let size = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) + 0.5;
        tris.extend(grid_box(lo, lo + size, 4));
    }
    let on = |t: &[DVec3; 3], rng: &mut form_factor::sampling::Rng| {
        let (u, v) = (rng.next_f64(), rng.next_f64());
        let (u, v) = if u + v > 1.0 {
            (1.0 - u, 1.0 - v)
        } else {
            (u, v)
        };
        t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0])
    };
    let segments = (0..1_000_000)
        .map(|_| {
            let (i, j) = (rng.below(tris.len()), rng.below(tris.len()));
            (
                on(&tris[i], &mut rng),
                on(&tris[j], &mut rng),
                [i as u32, j as u32],
            )
        })
        .collect();
    (tris, segments)
}

pub(super) fn rays(args: &Args) -> Result<String> {
    let (tris, segments) = ray_scene();
    let vis = Visibility::build(&tris);
    // One thread: rays per second per core.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let (ours, blocked) = pool.install(|| {
        let t = Instant::now();
        let blocked = segments
            .iter()
            .filter(|s| vis.occluded(s.0, s.1, s.2))
            .count();
        (segments.len() as f64 / t.elapsed().as_secs_f64(), blocked)
    });
    // The same triangles and segments for Embree: f32 little-endian, counts first.
    let bin = args.out.join("rays.bin");
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&(tris.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&(segments.len() as u64).to_le_bytes());
    for t in &tris {
        for v in t {
            for x in v.to_array() {
                bytes.extend_from_slice(&(x as f32).to_le_bytes());
            }
        }
    }
    for (p, q, _) in &segments {
        for x in p.to_array().into_iter().chain(q.to_array()) {
            bytes.extend_from_slice(&(x as f32).to_le_bytes());
        }
    }
    std::fs::write(&bin, bytes)?;
    let script = radiosity_tools::root().join("tools/embree_rays.py");
    let o = Command::new("python3").arg(&script).arg(&bin).output()?;
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let mut md = format!(
        "{} triangles, {} segments between random surface points; occlusion (any hit), one \
         thread.\n\n| engine | rays/s per core | blocked |\n|---|---|---|\n| radiosity \
         (own four-wide BVH, SIMD boxes and watertight triangle test) | {:.2} M | {} |\n",
        tris.len(),
        segments.len(),
        ours / 1e6,
        blocked
    );
    match text.lines().find(|l| l.starts_with("embree")) {
        Some(line) => {
            // "embree <rays per second> <blocked>"
            let f: Vec<&str> = line.split_whitespace().collect();
            let theirs: f64 = f[1].parse()?;
            writeln!(
                md,
                "| Embree 4 (embreex, rtcOccluded1 per ray) | {:.2} M | {} |",
                theirs / 1e6,
                f[2]
            )?;
            writeln!(md, "\nRatio ours / Embree: **{:.2}**.", ours / theirs)?;
        }
        None => writeln!(
            md,
            "\nEmbree could not be run here: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("no output")
        )?,
    }
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Mat-vec bandwidth
