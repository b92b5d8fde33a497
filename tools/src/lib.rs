//! The module the benchmark harnesses share (`benches/accuracy.rs`, run time against error;
//! `benches/scale.rs`, speed and scale): the date and machine lines of a summary,
//! least-squares fits of convergence orders and growth exponents, log-scale PNG charts drawn
//! with plotters (text through a TrueType font loaded at run time), per-surface means against
//! the path-traced reference, and the harnesses' command-line reading. Results go to
//! BENCHMARKS.md; the harnesses run with `cargo bench -p radiosity-tools --bench NAME`.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use plotters::prelude::*;
use radiosity::pipeline::Outcome;
use radiosity::scene::Scene;
use radiosity::validation::path_tracer;

/// The repository's root (this package is its `tools/`): where the shipped meshes and
/// `docs/bench/` are.
pub fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// The environment variable `name` as a positive, finite number, `None` where it is unset; an
/// error naming it and its value otherwise (`what` says what it should be: "length").
pub fn positive_env(name: &str, what: &str) -> Result<Option<f64>> {
    let Some(value) = std::env::var_os(name) else {
        return Ok(None);
    };
    let value = value.to_string_lossy();
    let x = value
        .parse()
        .ok()
        .filter(|x: &f64| x.is_finite() && *x > 0.0)
        .with_context(|| format!("{name}={value}: not a positive {what}"))?;
    Ok(Some(x))
}

/// The environment variable `name` as an axis, `x`, `y` or `z` (the scene's up, as
/// `--up` takes it: [`radiosity::scene::Up`]'s names), `None` where it is unset; an error
/// naming it and its value otherwise.
pub fn up_env(name: &str) -> Result<Option<radiosity::scene::Up>> {
    use radiosity::Choice;
    let Some(value) = std::env::var_os(name) else {
        return Ok(None);
    };
    let value = value.to_string_lossy();
    let up = radiosity::scene::Up::from_name(&value)
        .with_context(|| format!("{name}={value}: not an axis (x, y or z)"))?;
    Ok(Some(up))
}

/// What every harness's command line has: `--quick` (a smaller sweep), `--out DIR` (where the
/// results go) and `--help`; `cargo bench` adds `--bench`, which is ignored. Every other word is
/// kept, in order, in `other` for the harness to read (sections, internal options).
pub struct HarnessArgs {
    pub quick: bool,
    pub out: PathBuf,
    pub other: Vec<String>,
}

/// Reads the process's arguments (see [`HarnessArgs`]); `--help` prints `usage` and exits.
/// Works from the repository's root (`cargo bench` starts a harness in `tools/`), so the
/// shipped meshes, `docs/bench/` and every relative path (`--out`) are the root's.
pub fn harness_args(default_out: &str, usage: &str) -> Result<HarnessArgs> {
    std::env::set_current_dir(root())
        .with_context(|| format!("cannot work from {}", root().display()))?;
    let mut args = HarnessArgs {
        quick: false,
        out: PathBuf::from(default_out),
        other: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--quick" => args.quick = true,
            "--out" => args.out = it.next().context("--out needs a directory")?.into(),
            "--bench" => {}
            "-h" | "--help" => {
                println!("{usage}");
                std::process::exit(0);
            }
            _ => args.other.push(a),
        }
    }
    Ok(args)
}

/// The sections a harness's remaining arguments (`HarnessArgs::other`) name, each one of
/// `known`; `default` when they name none. `--child SPEC` (how a harness runs one measured
/// run in a process of its own) runs `child(SPEC)` and exits.
pub fn sections(
    words: Vec<String>,
    known: &[&str],
    default: &[&str],
    child: impl Fn(&str) -> Result<()>,
) -> Result<Vec<String>> {
    let mut sections = Vec::new();
    let mut it = words.into_iter();
    while let Some(word) = it.next() {
        if word == "--child" {
            child(&it.next().context("--child needs a run spec")?)?;
            std::process::exit(0);
        } else if known.contains(&word.as_str()) {
            sections.push(word);
        } else {
            return Err(unknown_argument(&word));
        }
    }
    if sections.is_empty() {
        sections = default.iter().map(|s| s.to_string()).collect();
    }
    Ok(sections)
}

/// The error for a word a harness does not know.
pub fn unknown_argument(word: &str) -> anyhow::Error {
    anyhow::anyhow!("unknown argument {word:?} (try --help)")
}

/// Fonts tried, in order, for chart text (Debian/Ubuntu, Fedora, Arch, macOS, Windows).
pub const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
    "/usr/share/fonts/noto/NotoSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Chart size, pixels.
pub const CHART: (u32, u32) = (640, 480);

/// Least-squares line y = a + b·x through the points: (a, b, r²). `None` with fewer than two
/// distinct x.
pub fn fit_line(points: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let syy: f64 = points.iter().map(|p| (p.1 - my).powi(2)).sum();
    if sxx <= 1e-300 {
        return None;
    }
    let b = sxy / sxx;
    let r2 = if syy > 0.0 {
        sxy * sxy / (sxx * syy)
    } else {
        1.0
    };
    Some((my - b * mx, b, r2))
}

/// The order p of error ≈ C·x^p: slope of log(error) against log(x), over positive finite points.
pub fn fit_order(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, e)| *x > 0.0 && *e > 0.0 && e.is_finite())
        .map(|(x, e)| (x.ln(), e.ln()))
        .collect();
    fit_line(&logs).map(|(_, b, r2)| (b, r2))
}

/// "YYYY-MM-DD HH:MM UTC" from the system clock, or `$BENCH_DATE` if set.
pub fn utc_date() -> String {
    if let Ok(d) = std::env::var("BENCH_DATE") {
        return d;
    }
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (y, m, d) = civil_from_days(secs.div_euclid(86_400));
    let t = secs.rem_euclid(86_400);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        t / 3600,
        t / 60 % 60
    )
}

/// Proleptic Gregorian (year, month, day) of a day count since 1970-01-01 (H. Hinnant,
/// "chrono-Compatible Low-Level Date Algorithms", `civil_from_days`).
pub fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097); // [0, 146096]
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // [0, 399]
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // [0, 365]
    let mp = (5 * doy + 2) / 153; // [0, 11], March = 0
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + (m <= 2) as i64;
    (y, m, d)
}

/// "CPU model, N cores" from /proc/cpuinfo and the available parallelism.
pub fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let rustc = std::process::Command::new("rustc")
        .arg("--version")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|v| format!(", {}", v.trim()))
        .unwrap_or_default();
    format!("{model}, {cores} cores{rustc}")
}

/// Register a TrueType font as plotters' "sans-serif"; false if none could be loaded.
pub fn load_font() -> bool {
    let candidates: Vec<String> = match std::env::var("BENCH_FONT") {
        Ok(p) => vec![p],
        Err(_) => FONT_PATHS.iter().map(|p| p.to_string()).collect(),
    };
    for path in candidates {
        if let Ok(bytes) = std::fs::read(&path) {
            // plotters keeps the font for the whole process.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                return true;
            }
        }
    }
    false
}

/// Ten distinguishable colours (Tableau 10).
pub const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// One curve of a chart.
pub struct Curve {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Index into [`COLOURS`].
    pub colour: usize,
    /// 0: solid line, filled circles; otherwise dashed line, triangles.
    pub style: usize,
}

/// "1e-3" at powers of ten, nothing elsewhere: log axes then label decades only.
pub fn decade_label(v: f64) -> String {
    let e = v.log10().round();
    if v > 0.0 && (v.log10() - e).abs() < 1e-6 {
        format!("1e{e}")
    } else {
        String::new()
    }
}

/// Draw curves on a log y axis and a log (`log_x`) or linear x axis into a PNG.
pub fn chart(
    path: &Path,
    title: &str,
    axes: (&str, &str),
    log_x: bool,
    curves: &[Curve],
    text: bool,
) -> Result<()> {
    let usable = |p: &(f64, f64)| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite();
    let all = || {
        curves
            .iter()
            .flat_map(|c| c.points.iter())
            .filter(|p| usable(p))
    };
    let (x0, x1) = all().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.0), b.max(p.0))
    });
    let (y0, y1) = all().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.1), b.max(p.1))
    });
    if !(x1 >= x0 && y1 >= y0) {
        eprintln!("warning: {}: nothing to plot", path.display());
        return Ok(());
    }
    let (x0, x1) = if log_x {
        (x0 / 1.5, x1 * 1.5)
    } else {
        (0.0, x1 * 1.02)
    };
    let y_range = (y0 / 2.0..y1 * 2.0).log_scale();
    let mut buf = vec![0u8; (CHART.0 * CHART.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, CHART).into_drawing_area();
        root.fill(&WHITE)?;
        let mut builder = ChartBuilder::on(&root);
        builder.margin(12);
        if text {
            builder
                .caption(title, ("sans-serif", 18))
                .x_label_area_size(36)
                .y_label_area_size(52);
        }
        // The same drawing code for both x coordinate types.
        macro_rules! draw {
            ($chart:expr, $x_label:expr) => {{
                let mut chart = $chart;
                let mut mesh = chart.configure_mesh();
                mesh.light_line_style(WHITE)
                    .bold_line_style(RGBColor(220, 220, 220));
                if text {
                    mesh.x_desc(axes.0)
                        .y_desc(axes.1)
                        .x_label_formatter(&$x_label)
                        .y_label_formatter(&|y: &f64| decade_label(*y));
                } else {
                    mesh.x_labels(0).y_labels(0);
                }
                mesh.draw()?;
                for c in curves {
                    let colour = COLOURS[c.colour % COLOURS.len()];
                    let pts: Vec<(f64, f64)> = c.points.iter().copied().filter(usable).collect();
                    let width = 2;
                    let series = if c.style == 0 {
                        chart
                            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(width)))?
                    } else {
                        chart.draw_series(DashedLineSeries::new(
                            pts.clone(),
                            6,
                            4,
                            colour.stroke_width(width),
                        ))?
                    };
                    if text {
                        series.label(c.label.clone()).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(width))
                        });
                    }
                    if pts.len() <= 12 {
                        if c.style == 0 {
                            chart.draw_series(
                                pts.iter().map(|&p| Circle::new(p, 3, colour.filled())),
                            )?;
                        } else {
                            chart.draw_series(
                                pts.iter()
                                    .map(|&p| TriangleMarker::new(p, 4, colour.filled())),
                            )?;
                        }
                    }
                }
                if text {
                    chart
                        .configure_series_labels()
                        .background_style(WHITE.mix(0.85))
                        .border_style(BLACK)
                        .label_font(("sans-serif", 11))
                        .position(SeriesLabelPosition::UpperRight)
                        .draw()?;
                }
            }};
        }
        if log_x {
            let chart = builder.build_cartesian_2d((x0..x1).log_scale(), y_range)?;
            draw!(chart, |x: &f64| format!("{x}"));
        } else {
            let chart = builder.build_cartesian_2d(x0..x1, y_range)?;
            draw!(chart, |x: &f64| format!("{x:.0}"));
        }
        root.present()?;
    }
    image::save_buffer(path, &buf, CHART.0, CHART.1, image::ExtendedColorType::Rgb8)
        .with_context(|| format!("writing {}", path.display()))
}

/// Runs each named section (`run` returns its Markdown) and writes it to `out/SECTION.md`,
/// headed by the date and machine; says on stderr what it is doing and how long it took.
pub fn write_sections(
    out: &Path,
    sections: &[String],
    mut run: impl FnMut(&str) -> Result<String>,
) -> Result<()> {
    std::fs::create_dir_all(out)?;
    let header = format!("Measured {} on {}.\n\n", utc_date(), machine());
    for s in sections {
        let t = std::time::Instant::now();
        eprintln!("== {s}");
        let md = run(s)?;
        let path = out.join(format!("{s}.md"));
        std::fs::write(&path, format!("{header}{md}"))?;
        eprintln!(
            "{} written ({:.0} s)",
            path.display(),
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Runs this harness again as `HARNESS --child SPEC` (one run in a process of its own, so its
/// peak memory is its own) and reads the JSON it prints on stdout.
pub fn run_child<T: serde::de::DeserializeOwned>(spec: &str) -> Result<T> {
    let exe = std::env::current_exe()?;
    let o = std::process::Command::new(exe)
        .args(["--child", spec])
        .output()?;
    if !o.status.success() {
        anyhow::bail!(
            "child {spec} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    serde_json::from_slice(&o.stdout).with_context(|| format!("child {spec}: its JSON"))
}

/// Bytes in MiB.
pub fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 20) as f64
}

/// Visible-area mean radiance per surface ([`path_tracer::solution_means`]) of a solved scene.
pub fn surface_means(scene: &Scene, out: &Outcome) -> Vec<[f64; 3]> {
    path_tracer::solution_means(
        scene,
        &out.patches,
        &out.solution.radiance,
        &out.visible_fraction,
    )
}

/// The path-traced per-surface visible means of the Cornell box
/// (docs/bench/cornell_reference.csv, made by `cargo bench -p radiosity-tools --bench scale --
/// reference`).
pub fn cornell_reference() -> Option<Vec<[f64; 3]>> {
    path_tracer::read_reference(&root().join("docs/bench/cornell_reference.csv")).ok()
}

/// Largest relative difference over surfaces and channels (channels where `reference` is 0
/// are skipped).
pub fn max_relative_difference(got: &[[f64; 3]], reference: &[[f64; 3]]) -> f64 {
    got.iter()
        .zip(reference)
        .flat_map(|(g, r)| (0..3).map(move |c| (g[c], r[c])))
        .filter(|(_, r)| *r > 0.0)
        .map(|(g, r)| (g - r).abs() / r)
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_line_recovers_an_exact_line() {
        let pts: Vec<(f64, f64)> = (0..5).map(|i| (i as f64, 2.0 - 0.5 * i as f64)).collect();
        let (a, b, r2) = fit_line(&pts).unwrap();
        assert!(
            (a - 2.0).abs() < 1e-12 && (b + 0.5).abs() < 1e-12,
            "{a} {b}"
        );
        assert!((r2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn fit_line_least_squares_of_noisy_points() {
        // y = x + (1, −1, −1, 1): residuals orthogonal to (1, x), so the fit is y = x.
        // By hand: x̄ = ȳ = 1.5, Sxx = 5, Sxy = 5, Syy = 9, so b = 1, a = 0, r² = 25/45.
        let pts = [(0.0, 1.0), (1.0, 0.0), (2.0, 1.0), (3.0, 4.0)];
        let (a, b, r2) = fit_line(&pts).unwrap();
        assert!((b - 1.0).abs() < 1e-12 && a.abs() < 1e-12, "{a} {b}");
        assert!((r2 - 25.0 / 45.0).abs() < 1e-12, "{r2}");
        assert!(fit_line(&[(1.0, 1.0)]).is_none());
        assert!(fit_line(&[(1.0, 1.0), (1.0, 2.0)]).is_none());
    }

    #[test]
    fn fit_order_of_a_power_law() {
        let pts: Vec<(f64, f64)> = [0.5, 0.25, 0.1].iter().map(|&h| (h, 3.0 * h * h)).collect();
        let (p, r2) = fit_order(&pts).unwrap();
        assert!((p - 2.0).abs() < 1e-12 && (r2 - 1.0).abs() < 1e-12, "{p}");
        // Zero and non-finite errors are left out, not turned into −∞.
        let mut with_zero = pts.clone();
        with_zero.push((0.05, 0.0));
        with_zero.push((0.01, f64::NAN));
        assert!((fit_order(&with_zero).unwrap().0 - 2.0).abs() < 1e-12);
    }

    #[test]
    fn decade_labels() {
        assert_eq!(decade_label(1e-3), "1e-3");
        assert_eq!(decade_label(1.0), "1e0");
        assert_eq!(decade_label(2e-3), "");
    }

    #[test]
    fn charts_are_drawn_without_a_font() {
        // No font registered: text = false must not touch plotters' text rendering.
        let dir = std::env::temp_dir().join(format!("radiosity-bench-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("chart.png");
        let curves = [Curve {
            label: "a".into(),
            points: vec![(0.1, 1e-2), (1.0, 1e-3), (2.0, 0.0)],
            colour: 0,
            style: 1,
        }];
        chart(&path, "t", ("x", "y"), true, &curves, false).unwrap();
        let png = image::open(&path).unwrap();
        assert_eq!((png.width(), png.height()), CHART);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn civil_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
        assert_eq!(civil_from_days(19_782), (2024, 2, 29));
        assert_eq!(civil_from_days(20_454), (2026, 1, 1));
    }
}
