//! The `skips` section: what each shortcut saves (its work with the shortcut on and off, and that
//! the answer does not change).

use super::*;

/// One skip measured: the same work with it off ("before") and on ("after").
pub(super) struct SkipRow {
    skip: &'static str,
    scene: &'static str,
    before: f64,
    after: f64,
    counter: String,
    same: String,
}

pub(super) fn skips(args: &Args) -> Result<String> {
    let cornell = cornell()?;
    let mut rows: Vec<SkipRow> = Vec::new();
    let same_radiance = |a: &Outcome, b: &Outcome| {
        if a.solution.radiance == b.solution.radiance {
            "identical".to_string()
        } else {
            let worst = a
                .solution
                .radiance
                .iter()
                .zip(&b.solution.radiance)
                .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs() / y[c].abs().max(1e-12)))
                .fold(0.0, f64::max);
            format!("max rel. diff {worst:.1e}")
        }
    };
    // Form-factor seconds of a run with a form-factor setting changed.
    let with = |scene: &Scene,
                base: &pipeline::Settings,
                f: &dyn Fn(&mut form_factor::Settings)|
     -> Result<(Outcome, f64)> {
        let mut s = base.clone();
        f(&mut s.form_factors);
        let (out, _) = run(scene, &s)?;
        let secs = out.report.seconds.form_factors;
        Ok((out, secs))
    };
    let mut base = settings(60.0);
    base.refine_rounds = 0;

    // 1. Faces on the convex hull leave the occlusion BVH.
    let (off, t_off) = with(&cornell, &base, &|f| f.shortcuts.skip_hull = false)?;
    let (on, t_on) = with(&cornell, &base, &|_| {})?;
    rows.push(SkipRow {
        skip: "hull faces out of the occlusion tests",
        scene: "Cornell box, 3160 patches",
        before: t_off,
        after: t_on,
        counter: format!(
            "occluder_patches {} of {}",
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .occluder_patches,
            on.patches.len()
        ),
        same: same_radiance(&on, &off),
    });
    // 2. Convex enclosure: no visibility ray at all.
    let sphere =
        scenes::integrating_sphere(1.0, if args.quick { 3 } else { 4 }, 30.0, 0.5, [1.0; 3])?;
    let mut sb = settings(10.0);
    sb.refine_rounds = 0;
    let (off, t_off) = with(&sphere, &sb, &|f| f.shortcuts.skip_hull = false)?;
    let (on, t_on) = with(&sphere, &sb, &|_| {})?;
    rows.push(SkipRow {
        skip: "convex enclosure: no visibility rays",
        scene: "integrating sphere",
        before: t_off,
        after: t_on,
        counter: format!(
            "convex_enclosure {}, rays {:.2e} → {:.2e}",
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .convex_enclosure,
            off.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .rays_cast as f64,
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .rays_cast as f64
        ),
        same: same_radiance(&on, &off),
    });
    // 3. Pairs behind each other's plane.
    let (off, t_off) = with(&cornell, &base, &|f| f.shortcuts.cull_behind = false)?;
    let (on, t_on) = with(&cornell, &base, &|_| {})?;
    rows.push(SkipRow {
        skip: "pairs behind each other's plane",
        scene: "Cornell box, 3160 patches",
        before: t_off,
        after: t_on,
        counter: format!(
            "pairs_culled {} of {}",
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .pairs_culled,
            on.form_factors.as_ref().expect("matrix method").stats.pairs
        ),
        same: same_radiance(&on, &off),
    });
    // 4. Black patches' rows.
    let mut black = cornell.clone();
    for m in &mut black.materials {
        if m.name == "red" || m.name == "green" {
            m.reflectance = [0.0; 3];
        }
    }
    let (off, t_off) = with(&black, &base, &|f| f.shortcuts.skip_unneeded = false)?;
    let (on, t_on) = with(&black, &base, &|_| {})?;
    rows.push(SkipRow {
        skip: "rows of black patches (ρ = 0)",
        scene: "Cornell box, red and green walls black",
        before: t_off,
        after: t_on,
        counter: format!(
            "rows_skipped {}",
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .rows_skipped
        ),
        same: same_radiance(&on, &off),
    });
    // 5. One bounce: only the emitters' columns.
    let mut direct = base.clone();
    direct.solver.method = Method::Neumann;
    direct.solver.bounces = 1;
    let (off, t_off) = with(&cornell, &direct, &|f| f.shortcuts.skip_unneeded = false)?;
    let (on, t_on) = with(&cornell, &direct, &|_| {})?;
    rows.push(SkipRow {
        skip: "--bounces 1: emitters' columns only",
        scene: "Cornell box, 3160 patches",
        before: t_off,
        after: t_on,
        counter: format!(
            "pairs_skipped {} of {}",
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .pairs_skipped,
            on.form_factors.as_ref().expect("matrix method").stats.pairs
        ),
        same: same_radiance(&on, &off),
    });
    // 6. No emitters: a black result at once.
    let mut dark = cornell.clone();
    for m in &mut dark.materials {
        m.emission = [0.0; 3];
    }
    let (_, t_lit) = run(&cornell, &base)?;
    let (d, t_dark) = run(&dark, &base)?;
    rows.push(SkipRow {
        skip: "no emitters: no form factors, no solve",
        scene: "Cornell box with the light off (before: lit)",
        before: t_lit,
        after: t_dark,
        counter: format!("warning: {:?}", d.report.warnings.first().map(|w| &w[..30])),
        same: "black".into(),
    });
    // 7. Refinement rounds reuse unchanged pairs.
    let (off, t_off) = with(&cornell, &settings(60.0), &|f| f.shortcuts.reuse = false)?;
    let (on, t_on) = with(&cornell, &settings(60.0), &|_| {})?;
    rows.push(SkipRow {
        skip: "refinement reuses unchanged pairs",
        scene: "Cornell box, default (2 rounds)",
        before: t_off,
        after: t_on,
        counter: format!(
            "pairs_reused {} (last round)",
            on.form_factors
                .as_ref()
                .expect("matrix method")
                .stats
                .pairs_reused
        ),
        same: format!(
            "per-surface means within {:.1e} of each other (other sample pairings, so other \
             refinement marks: {} vs {} patches)",
            surface_difference(&cornell, &on, &off),
            on.patches.len(),
            off.patches.len()
        ),
    });
    // 8. The form-factor cache.
    let dir = args.out.join("ff-cache");
    let _ = std::fs::remove_dir_all(&dir);
    let mut cached = settings(60.0);
    cached.cache = Some(dir.clone());
    let (first, t_first) = run(&cornell, &cached)?;
    let mut relit = cornell.clone();
    for m in &mut relit.materials {
        if m.name == "light" {
            m.emission = [4.0, 8.0, 17.0];
        }
    }
    cached.refine_rounds = 0;
    let (_, _) = run(&cornell, &cached)?; // stores the unrefined F too
    let (hit, t_hit) = run(&relit, &cached)?;
    let mut plain = settings(60.0);
    plain.refine_rounds = 0;
    let (fresh, t_fresh) = run(&relit, &plain)?;
    let _ = first;
    let _ = t_first;
    rows.push(SkipRow {
        skip: "--cache: relighting reads F",
        scene: "Cornell box relit, 3160 patches",
        before: t_fresh,
        after: t_hit,
        counter: format!(
            "cache hits {}, seconds_saved {:.2}",
            hit.report.cache.as_ref().map_or(0, |c| c.hits),
            hit.report.cache.as_ref().map_or(0.0, |c| c.seconds_saved)
        ),
        same: same_radiance(&hit, &fresh),
    });
    let _ = std::fs::remove_dir_all(&dir);
    // 9. Grey scenes solve one channel.
    let furnace = scenes::furnace_room(0.9, 1.0)?;
    let mut fs = settings(0.1);
    fs.form_factors.estimator = Estimator::Hemisphere;
    fs.form_factors.rays = 256;
    fs.solver.tolerance = 1e-10;
    let (grey, _) = run(&furnace, &fs)?;
    let system = |out: &Outcome, rho: &[[f64; 3]]| -> Result<(f64, solve::Solution)> {
        let sys = System {
            form_factors: out.form_factors.as_ref().expect("matrix method"),
            reflectance: rho,
            emission: &out.patches.emission,
        };
        let t = Instant::now();
        let s = solve::solve(&sys, &fs.solver)?;
        Ok((t.elapsed().as_secs_f64(), s))
    };
    let (t_grey, sg) = system(&grey, &grey.patches.reflectance)?;
    let tinted: Vec<[f64; 3]> = grey
        .patches
        .reflectance
        .iter()
        .map(|r| [r[0], r[1], r[2] * (1.0 - 1e-12)])
        .collect();
    let (t_rgb, sr) = system(&grey, &tinted)?;
    let diff = sg
        .radiance
        .iter()
        .zip(&sr.radiance)
        .map(|(a, b)| (a[0] - b[0]).abs() / b[0])
        .fold(0.0, f64::max);
    rows.push(SkipRow {
        skip: "grey scene: one channel",
        scene: "furnace room ρ = 0.9, solve only",
        before: t_rgb,
        after: t_grey,
        counter: format!("grey {} vs {}", sg.grey, sr.grey),
        same: format!("max rel. diff {diff:.1e} (ρ_blue changed by 1e-12)"),
    });
    // 10. The solve stops at the tolerance.
    let mut fixed = fs.solver;
    fixed.tolerance = 1e-300;
    fixed.max_iterations = 200;
    let sys = System {
        form_factors: grey.form_factors.as_ref().expect("matrix method"),
        reflectance: &grey.patches.reflectance,
        emission: &grey.patches.emission,
    };
    let t = Instant::now();
    let all = solve::solve(&sys, &fixed)?;
    let t_fixed = t.elapsed().as_secs_f64();
    rows.push(SkipRow {
        skip: "solve stops at the tolerance (1e-10)",
        scene: "furnace room ρ = 0.9 (before: until a sweep changes nothing)",
        before: t_fixed,
        after: t_grey,
        counter: format!("iterations {} vs {}", sg.iterations, all.iterations),
        same: format!("residual {:.1e} vs {:.1e}", sg.residual, all.residual),
    });

    let mut csv = String::from("skip,scene,before_s,after_s,speedup,counter,same\n");
    let mut md = String::from(
        "| skip | scene | without (s) | with (s) | gain | counter in --report | answer |\n|---|---|---|---|---|---|---|\n",
    );
    for r in &rows {
        let gain = r.before / r.after.max(1e-9);
        writeln!(
            csv,
            "{},{},{:.4},{:.4},{:.2},\"{}\",\"{}\"",
            r.skip, r.scene, r.before, r.after, gain, r.counter, r.same
        )?;
        writeln!(
            md,
            "| {} | {} | {:.3} | {:.3} | {:.1}× | {} | {} |",
            r.skip, r.scene, r.before, r.after, gain, r.counter, r.same
        )?;
    }
    std::fs::write(args.out.join("skips.csv"), csv)?;
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Solvers
