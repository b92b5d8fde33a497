//! The `rays` section: visibility rays per second on the form-factor workload, and the same
//! segments for Embree (tools/embree_rays.py).

use super::*;

/// An occlusion query: two points and the triangles they lie on.
type Segment = (glam::DVec3, glam::DVec3, [u32; 2]);

/// A closed room of 26 × 26 squares per face with ten boxes inside, 10,032 triangles (the
/// scene of `visibility::tests::throughput`), and 1M segments between random surface points.
pub(super) fn ray_scene() -> (Vec<[glam::DVec3; 3]>, Vec<Segment>) {
    use glam::DVec3;
    let mut rng = radiosity::sampling::Rng::new(&[6]);
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
    let on = |t: &[DVec3; 3], rng: &mut radiosity::sampling::Rng| {
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
    let pairs: Vec<_> = segments.iter().map(|s| (s.0, s.1)).collect();
    let embree = embree(args, "rays.bin", &tris, &pairs)?;
    let mut md = format!(
        "{} triangles, {} segments between random surface points; occlusion (any hit), one \
         thread.\n\n| engine | rays/s per core | blocked |\n|---|---|---|\n| radiosity \
         (own four-wide BVH, SIMD boxes and watertight triangle test) | {:.2} M | {} |\n",
        tris.len(),
        segments.len(),
        ours / 1e6,
        blocked
    );
    match embree {
        Ok((theirs, their_blocked)) => {
            writeln!(
                md,
                "| Embree 4 (embreex, rtcOccluded1 per ray) | {:.2} M | {} |",
                theirs / 1e6,
                their_blocked
            )?;
            writeln!(md, "\nRatio ours / Embree: **{:.2}**.", ours / theirs)?;
        }
        Err(why) => writeln!(md, "\nEmbree could not be run here: {why}")?,
    }
    md.push_str(&form_factor_workloads(args)?);
    Ok(md)
}

/// Embree's occlusion rays per second on one thread and its count of blocked segments, for
/// `tris` and the open segments `segments` (tools/embree_rays.py, through `name` in the output
/// directory), or why it could not run.
fn embree(
    args: &Args,
    name: &str,
    tris: &[[glam::DVec3; 3]],
    segments: &[(glam::DVec3, glam::DVec3)],
) -> Result<std::result::Result<(f64, u64), String>> {
    // The triangles and segments, f32 little-endian, counts first.
    let bin = args.out.join(name);
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&(tris.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&(segments.len() as u64).to_le_bytes());
    for t in tris {
        for v in t {
            for x in v.to_array() {
                bytes.extend_from_slice(&(x as f32).to_le_bytes());
            }
        }
    }
    for (p, q) in segments {
        for x in p.to_array().into_iter().chain(q.to_array()) {
            bytes.extend_from_slice(&(x as f32).to_le_bytes());
        }
    }
    std::fs::write(&bin, bytes)?;
    let script = radiosity_tools::root().join("tools/embree_rays.py");
    let o = Command::new("python3").arg(&script).arg(&bin).output()?;
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    std::fs::remove_file(&bin).ok();
    Ok(match text.lines().find(|l| l.starts_with("embree")) {
        Some(line) => {
            // "embree <rays per second> <blocked>"
            let f: Vec<&str> = line.split_whitespace().collect();
            Ok((f[1].parse()?, f[2].parse()?))
        }
        None => Err(String::from_utf8_lossy(&o.stderr)
            .lines()
            .last()
            .unwrap_or("no output")
            .to_string()),
    })
}

/// One gathering point of the form-factor loop and its segments: the point, the occluding
/// triangle it lies on (or `NONE`), and each target with the occluding triangle it lies on.
struct Row {
    origin: glam::DVec3,
    ignore: u32,
    targets: Vec<(glam::DVec3, u32)>,
}

/// The visibility workload of the pair loop (src/form_factor/pair.rs) on `scene` cut at
/// `max_edge`: the occluders as it traces them (the scene triangles off the convex hull,
/// `form_factor::Coarse`), and for the rows of every `stride`-th patch i, from each of its
/// three Gauss points x_k the segment to the paired Gauss point y of every later patch j, when
/// neither patch lies behind the other and each end lies in front of the other's patch (the
/// pair loop's rule; the pairing shift is `(i + j) mod 3` here, and burial is left out).
fn form_factor_workload(
    scene: &Scene,
    max_edge: f64,
    stride: usize,
) -> Result<(usize, Vec<[glam::DVec3; 3]>, Vec<Row>)> {
    use glam::DVec3;
    let patches =
        radiosity::mesh::subdivide(scene, max_edge, radiosity::mesh::DEFAULT_CREASE_DEGREES)?;
    let n = patches.len();
    let coarse = form_factor::Coarse::of(&patches, &form_factor::occluders(&patches));
    let rule = radiosity::sampling::gauss_rule(3).expect("a 3-point rule");
    let points: Vec<[DVec3; 3]> = (0..n)
        .map(|i| {
            let t = patches.corners(i);
            std::array::from_fn(|k| {
                let b = rule[k].0;
                b[0] * t[0] + b[1] * t[1] + b[2] * t[2]
            })
        })
        .collect();
    let mut rows = Vec::new();
    for i in (0..n).step_by(stride) {
        let (ni, ti) = (patches.normal[i], patches.corners(i));
        let mut row: [Row; 3] = std::array::from_fn(|k| Row {
            origin: points[i][k],
            ignore: coarse.of_patch[i],
            targets: Vec::new(),
        });
        for j in i + 1..n {
            let (nj, tj) = (patches.normal[j], patches.corners(j));
            let behind =
                |n: DVec3, c: DVec3, t: &[DVec3; 3]| t.iter().all(|v| n.dot(*v - c) <= 0.0);
            if behind(ni, patches.centroid[i], &tj) || behind(nj, patches.centroid[j], &ti) {
                continue;
            }
            for (k, r) in row.iter_mut().enumerate() {
                let y = points[j][(k + i + j) % 3];
                let d = y - r.origin;
                if ni.dot(d) > 0.0 && nj.dot(d) < 0.0 {
                    r.targets.push((y, coarse.of_patch[j]));
                }
            }
        }
        rows.extend(row);
    }
    Ok((n, coarse.triangles, rows))
}

/// Occlusion throughput on the form-factor workload ([`form_factor_workload`]): the Cornell box
/// at about 3,160 and 12,640 patches and the furnished hall (many occluders), one thread, as
/// single rays through the BVH, through each gathering point's light buffer
/// (`visibility::LightBuffer`, the bundle of a point's segments), and by Embree.
fn form_factor_workloads(args: &Args) -> Result<String> {
    use radiosity::visibility::LightBuffer;
    let mut md = String::from(
        "\n### The form-factor workload\n\nThe segments the pair loop casts (every `stride`-th \
         patch's rows: from each of its three Gauss points to the paired point of every later \
         patch in front of it), against the occluders it traces (the scene triangles off the \
         convex hull); one thread. *Single*: each segment through the BVH \
         (`Visibility::occluded_points`). *Bundle*: the segments of one gathering point through \
         its light buffer (`visibility::LightBuffer`), the buffer's construction included. \
         Answers are checked equal segment by segment.\n\n\
         | scene | patches | occluding triangles | segments | blocked | single, rays/s | bundle, rays/s | Embree, rays/s | single / Embree | bundle / Embree |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let cornell = cornell()?;
    let hall = scenes::furnished_hall(10_000)?;
    let cases: [(&str, &Scene, f64, usize); 3] = [
        ("Cornell box", &cornell, 67.5, 3),
        ("Cornell box", &cornell, 33.8, 40),
        ("furnished hall, 10⁴ triangles", &hall, 1.0, 24),
    ];
    for (name, scene, max_edge, stride) in cases {
        let (patches, tris, rows) = form_factor_workload(scene, max_edge, stride)?;
        let vis = Visibility::build(&tris);
        let prepared: Vec<_> = rows
            .iter()
            .map(|r| {
                let targets: Vec<_> = r
                    .targets
                    .iter()
                    .map(|&(y, ig)| (vis.point(y), ig))
                    .collect();
                (vis.point(r.origin), r.ignore, targets)
            })
            .collect();
        let segments: usize = rows.iter().map(|r| r.targets.len()).sum();
        let (single, bundle, blocked) = pool.install(|| -> Result<(f64, f64, usize)> {
            let t = Instant::now();
            let mut single_answers = Vec::with_capacity(segments);
            for (p, ig, targets) in &prepared {
                for (q, jg) in targets {
                    single_answers.push(vis.occluded_points(p, q, [*ig, *jg]));
                }
            }
            let single = segments as f64 / t.elapsed().as_secs_f64();
            let t = Instant::now();
            let mut buffer = LightBuffer::new(&vis);
            let mut bundle_answers = Vec::with_capacity(segments);
            for (p, ig, targets) in &prepared {
                buffer.aim(p, *ig);
                for (q, jg) in targets {
                    bundle_answers.push(buffer.occluded(q, *jg));
                }
            }
            let bundle = segments as f64 / t.elapsed().as_secs_f64();
            anyhow::ensure!(
                single_answers == bundle_answers,
                "light buffer and BVH disagree"
            );
            Ok((
                single,
                bundle,
                single_answers.iter().filter(|&&b| b).count(),
            ))
        })?;
        let pairs: Vec<_> = rows
            .iter()
            .flat_map(|r| r.targets.iter().map(|&(y, _)| (r.origin, y)))
            .collect();
        let (theirs, their_blocked) = match embree(args, "ff_rays.bin", &tris, &pairs)? {
            Ok((rate, b)) => (rate, b.to_string()),
            Err(why) => {
                eprintln!("Embree could not be run: {why}");
                (f64::NAN, "–".into())
            }
        };
        writeln!(
            md,
            "| {name} (max edge {max_edge}, stride {stride}) | {patches} | {} | {segments} | {blocked} (Embree {their_blocked}) | {:.2} M | {:.2} M | {:.2} M | {:.2} | {:.2} |",
            tris.len(),
            single / 1e6,
            bundle / 1e6,
            theirs / 1e6,
            single / theirs,
            bundle / theirs
        )?;
    }
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Mat-vec bandwidth
