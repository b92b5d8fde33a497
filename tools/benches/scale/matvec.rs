//! The `matvec` section: the bandwidth of one product with F against the machine's memory
//! bandwidth.

use super::*;

pub(super) fn matvec(args: &Args) -> Result<String> {
    let scene = cornell()?;
    let mut s = settings(if args.quick { 45.0 } else { 30.0 });
    s.refine_rounds = 0;
    s.form_factors.estimator = Estimator::Hemisphere;
    s.form_factors.rays = 2048;
    s.solver.method = Method::Neumann;
    s.solver.bounces = 0;
    s.form_factors.shortcuts.skip_unneeded = false;
    let (out, _) = run(&scene, &s)?;
    let m = &out.form_factors.as_ref().expect("matrix method").matrix;
    let (n, nnz) = (m.rows(), m.nnz());
    let x: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, 1.0, 0.5]).collect();
    let mut y = vec![[0.0f64; 3]; n];
    let reps = 20;
    let sys = System {
        form_factors: out.form_factors.as_ref().expect("matrix method"),
        reflectance: &out.patches.reflectance,
        emission: &out.patches.emission,
    };
    let t = Instant::now();
    for _ in 0..reps {
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let (cols, vals) = sys.row(i);
            let mut acc = [0.0f64; 3];
            for (&j, &f) in cols.iter().zip(vals) {
                let xj = &x[j as usize];
                for c in 0..3 {
                    acc[c] += f as f64 * xj[c];
                }
            }
            *yi = acc;
        });
    }
    let secs = t.elapsed().as_secs_f64() / reps as f64;
    // Bytes the product must move at least: every value (f32) and column index (u32) once,
    // the row pointers, and L read and written once (x is small enough to stay in cache).
    let bytes = (nnz * 8 + (n + 1) * 4 + 2 * n * 24) as f64;
    // The machine's bandwidth, with every core, on 512 MiB (pages touched first, so no page
    // faults are timed): reading it (a sum, what a product mostly does) and copying it (read
    // + write counted).
    use rayon::prelude::*;
    let len = 64 << 20;
    let mut src: Vec<f64> = (0..len).into_par_iter().map(|i| i as f64).collect();
    let mut dst = vec![0.0f64; len];
    dst.par_chunks_mut(1 << 16).for_each(|d| d.fill(1.0));
    let t = Instant::now();
    let mut total = 0.0;
    for _ in 0..3 {
        // Eight independent sums per chunk: bound by memory, not by the latency of one chain.
        total += src
            .par_chunks(1 << 16)
            .map(|s| {
                let mut acc = [0.0f64; 8];
                for c in s.chunks_exact(8) {
                    for (a, x) in acc.iter_mut().zip(c) {
                        *a += x;
                    }
                }
                acc.iter().sum::<f64>()
            })
            .sum::<f64>();
    }
    let read = (3 * len * 8) as f64 / t.elapsed().as_secs_f64();
    std::hint::black_box(total);
    // Back and forth, so that no copy is a dead store the compiler may drop.
    let t = Instant::now();
    for k in 0..4 {
        let (to, from) = if k % 2 == 0 {
            (&mut dst, &src)
        } else {
            (&mut src, &dst)
        };
        to.par_chunks_mut(1 << 16)
            .zip(from.par_chunks(1 << 16))
            .for_each(|(d, s)| d.copy_from_slice(s));
        std::hint::black_box(&*to);
    }
    let copy = (4 * 2 * len * 8) as f64 / t.elapsed().as_secs_f64();
    let rate = bytes / secs;
    Ok(format!(
        "F of the Cornell box with {n} patches, {nnz} non-zeros (f32 values, u32 columns); y = F·x \
         for three channels at once with every core, mean of {reps}.\n\n| | bytes/s |\n|---|---|\n\
         | F·x ({:.1} ms, {:.0} MiB moved) | {:.2} GB/s |\n| memory read (sum), 512 MiB | {:.2} \
         GB/s |\n| memory copy, 512 MiB (read + write) | {:.2} GB/s |\n\nFraction of the read \
         bandwidth: **{:.2}**; of the copy bandwidth: {:.2}.\n",
        secs * 1e3,
        bytes / (1 << 20) as f64,
        rate / 1e9,
        read / 1e9,
        copy / 1e9,
        rate / read,
        rate / copy
    ))
}

// ---------------------------------------------------------------------------------------------
// The path-traced reference
