//! Solving (I − K) L = E for the patch radiance L, per RGB channel, with K = diag(ρ)·F. Five
//! methods behind one entry point [`solve`]:
//!
//! - **Neumann** (`--bounces N`): L = Σ_{b=0}^{N} K^b E exactly; term b is the light after b
//!   bounces, so N = 1 is direct illumination (emission plus one reflection).
//! - **Jacobi**: L⁽ᵏ⁺¹⁾ = E + K L⁽ᵏ⁾ from L⁽⁰⁾ = E. Its iterates are the Neumann partial sums,
//!   and since E − (I − K)L⁽ᵏ⁾ = L⁽ᵏ⁺¹⁾ − L⁽ᵏ⁾ the residual costs nothing extra. Converges
//!   because ‖K‖∞ ≤ max ρ · max row sum < 1 (Cohen & Wallace §5.3), by that factor per sweep.
//! - **Gauss–Seidel** with over-relaxation ω (`--omega`, SOR): the same update, in place, row
//!   by row, so each row uses the newest values of the rows before it — exactly, yet on every
//!   core: each row's sum is split by column into the part that is known before the sweep
//!   (rows after it), the part known once the earlier row blocks are done, and a small
//!   sequential remainder (see [`stationary`]).
//! - **Conjugate gradient** on the symmetric form ([`cg`]): row i multiplied by a_i/ρ_i (a_i
//!   the patch's visible area) turns the system into (diag(a/ρ) − A·F) L = diag(a/ρ) E, whose
//!   matrix is symmetric when A·F is (reciprocity, a_i F_ij = a_j F_ji) and diagonally
//!   dominant, hence positive definite. Estimated form factors are reciprocal only up to their
//!   error, so CG solves with A·F replaced by its symmetric part — the system `--reciprocity`
//!   gives — and rows with ρ_i = 0 eliminated (L_i = E_i). Sweeps grow as 1/√(1 − ρ) instead
//!   of 1/(1 − ρ).
//! - **Southwell** (progressive refinement, [`southwell`]): shoot the patch with the most
//!   unshot power, repeatedly (Cohen, Chen, Wallace & Greenberg, "A progressive refinement
//!   approach to fast radiosity image generation", SIGGRAPH 1988). The unshot radiance is
//!   exactly the residual, and the brightest sources are shot first, so a few shots already
//!   give a useful image.
//!
//! The iterative methods stop when the relative residual ‖E − (I − K)L‖₂ / ‖E‖₂ ≤ tolerance
//! (for CG: that of the symmetric system it solves) or after `max_iterations` sweeps
//! (Southwell: n shots count as one sweep); [`Solution::converged`] says which, and the
//! caller must not hide it. A grey scene (ρ and Le equal in the three channels on every
//! patch) is solved in one channel and copied: a third of the arithmetic.

pub mod anderson;
pub mod cg;
pub mod southwell;
pub mod stationary;
pub mod system;

use std::fmt;

use serde::Serialize;

pub use system::{norm, Problem, System};

use crate::choice::Choice;
use crate::color::Rgb;
use crate::{Error, Result};

/// The solution method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Jacobi iteration from L = E.
    Jacobi,
    /// Gauss–Seidel iteration (SOR with `omega`), in fixed parallel blocks.
    GaussSeidel,
    /// Truncated Neumann series E + KE + … + K^N E (N = `bounces`).
    Neumann,
    /// Conjugate gradient on the symmetric (reciprocity-enforced) form.
    Cg,
    /// Southwell / progressive refinement: shoot the largest unshot power first.
    Southwell,
}

impl Choice for Method {
    const SETTING: &'static str = "solver.method";
    const ALL: &'static [Method] = &[
        Method::Jacobi,
        Method::GaussSeidel,
        Method::Neumann,
        Method::Cg,
        Method::Southwell,
    ];

    fn name(self) -> &'static str {
        match self {
            Method::Jacobi => "jacobi",
            Method::GaussSeidel => "gauss-seidel",
            Method::Neumann => "neumann",
            Method::Cg => "cg",
            Method::Southwell => "southwell",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Method::Jacobi => "Jacobi iteration from L = E",
            Method::GaussSeidel => {
                "Gauss–Seidel iteration (SOR with `omega`), in fixed parallel blocks"
            }
            Method::Neumann => "Truncated Neumann series E + KE + … + K^N E (N = `bounces`)",
            Method::Cg => "Conjugate gradient on the symmetric (reciprocity-enforced) form",
            Method::Southwell => {
                "Southwell / progressive refinement: shoot the largest unshot power first"
            }
        }
    }
}

impl Method {
    /// The method's name ([`Choice::name`]), callable without importing the trait.
    pub fn name(self) -> &'static str {
        Choice::name(self)
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Settings {
    /// The method.
    pub method: Method,
    /// Relative residual at which the iterative methods stop; > 0.
    pub tolerance: f64,
    /// Sweep limit of the iterative methods (Southwell: n shots per sweep); ≥ 1.
    pub max_iterations: u32,
    /// Number of bounces N of the Neumann series.
    pub bounces: u32,
    /// Over-relaxation factor ω of Gauss–Seidel, in (0, 2); 1 = plain Gauss–Seidel; `None`
    /// = automatic ([`auto_omega`]).
    pub omega: Option<f64>,
}

/// Largest ω the automatic choice takes: at 1.9 SOR diverged on the furnace room at ρ ≥ 0.99
/// (BENCHMARKS.md, "Solvers"); at 1.7 it converged everywhere measured.
pub const MAX_AUTO_OMEGA: f64 = 1.7;

/// Automatic over-relaxation: Young's optimum ω = 2 / (1 + √(1 − q²)) for a Jacobi
/// convergence factor q, with q bounded by max_i ρ_i Σ_j F_ij (the largest channel), capped at
/// [`MAX_AUTO_OMEGA`] (D. M. Young, *Iterative Solution of Large Linear Systems*, 1971, for
/// consistently ordered matrices; the solver benchmark, BENCHMARKS.md "Solvers", finds
/// Gauss–Seidel's factor per sweep to be q², as that theory says, and the best ω of a scan
/// within 0.1 of the formula up to the cap).
/// If it diverges anyway, the solve falls back to ω = 1.
pub fn auto_omega(system: &System) -> f64 {
    let sums = system.form_factors.row_sums();
    let q = system
        .reflectance
        .iter()
        .zip(&sums)
        .map(|(r, s)| r.iter().cloned().fold(0.0, f64::max) * s)
        .fold(0.0, f64::max)
        .min(1.0);
    (2.0 / (1.0 + (1.0 - q * q).sqrt())).min(MAX_AUTO_OMEGA)
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::GaussSeidel,
            tolerance: 1e-6,
            max_iterations: 10_000,
            bounces: 1,
            omega: None,
        }
    }
}

impl Settings {
    /// Checks the ranges before any work: `tolerance` finite and > 0, `max_iterations` ≥ 1,
    /// `omega` (when given) in (0, 2). Errors are [`Error::Setting`] named `solver.tolerance`,
    /// `solver.max_iterations`, `solver.omega`.
    pub fn validate(&self) -> Result<()> {
        if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
            return Err(Error::setting(
                "solver.tolerance",
                format!("{} is not a positive number", self.tolerance),
            ));
        }
        if self.max_iterations == 0 {
            return Err(Error::setting(
                "solver.max_iterations",
                "must be at least 1",
            ));
        }
        if let Some(w) = self.omega {
            if !(w > 0.0 && w < 2.0) {
                return Err(Error::setting(
                    "solver.omega",
                    format!("{w} is not in (0, 2): over-relaxation diverges outside"),
                ));
            }
        }
        Ok(())
    }
}

/// The solved radiance and how it was obtained.
#[derive(Debug, Clone, Serialize)]
pub struct Solution {
    /// Radiance of every patch, W·sr⁻¹·m⁻² per RGB channel.
    #[serde(skip)]
    pub radiance: Vec<Rgb>,
    /// Sweeps (Jacobi, Gauss–Seidel, CG: one product with the matrix each), bounces (Neumann)
    /// or shots (Southwell) performed.
    pub iterations: u32,
    /// Final relative residual ‖E − (I − K)L‖₂ / ‖E‖₂ of the returned L (CG: of the
    /// symmetric system it solves).
    pub residual: f64,
    /// Relative residual after each sweep (Southwell: after every n shots; Neumann: the
    /// final one).
    pub residual_history: Vec<f64>,
    /// False when an iterative method hit `max_iterations` above the tolerance.
    pub converged: bool,
    /// True when the scene was grey and solved in one channel.
    pub grey: bool,
    /// The over-relaxation Gauss–Seidel used (1 for the other methods).
    pub omega: f64,
    /// The method that solved it.
    pub method: Method,
}

/// Reports one sweep to the progress observer (a status line; no effect on the result).
pub(crate) fn report_sweep(iteration: u32, residual: f64) {
    crate::progress::note_status(|| format!("sweep {iteration}: residual {residual:.2e}"));
}

/// The time left of an iteration whose residual falls geometrically, for the progress
/// display: a stationary iteration's error shrinks by the spectral radius q of its iteration
/// matrix each sweep once the slowest mode dominates, so from the last two residuals
/// r_{k−1}, r_k (q ≈ r_k / r_{k−1}) the sweeps left to the tolerance τ are
/// ln(τ / r_k) / ln q, each taking the mean time of the sweeps so far.
pub(crate) struct SweepClock {
    started: std::time::Instant,
    sweeps: u32,
    previous: Option<f64>,
    tolerance: f64,
}

impl SweepClock {
    /// A clock for sweeps toward `tolerance` (relative residual).
    pub(crate) fn new(tolerance: f64) -> SweepClock {
        SweepClock {
            started: std::time::Instant::now(),
            sweeps: 0,
            previous: None,
            tolerance,
        }
    }

    /// Reports sweep `iteration` with `residual`, and the time left when the residual falls
    /// steadily (a status line; no effect on the result).
    pub(crate) fn report(&mut self, iteration: u32, residual: f64) {
        self.sweeps += 1;
        let left = self
            .previous
            .and_then(|p| sweeps_left(p, residual, self.tolerance));
        self.previous = Some(residual);
        let per_sweep = self.started.elapsed().as_secs_f64() / self.sweeps as f64;
        crate::progress::note_status(|| match left {
            Some(n) => format!(
                "sweep {iteration}: residual {residual:.2e}, about {n} more ({} left)",
                crate::progress::duration(n as f64 * per_sweep)
            ),
            None => format!("sweep {iteration}: residual {residual:.2e}"),
        });
    }
}

/// Sweeps left from residual `now` (the previous one `before`) to `tolerance` at the rate
/// now / before; `None` unless the residual is falling and still above the tolerance.
pub(crate) fn sweeps_left(before: f64, now: f64, tolerance: f64) -> Option<u32> {
    let q = now / before;
    if !(q > 0.0 && q < 1.0 && now > tolerance && tolerance > 0.0) {
        return None;
    }
    Some(((tolerance / now).ln() / q.ln()).ceil().min(1e6) as u32)
}

/// What one method returns: the radiance in C channels and its bookkeeping.
pub(crate) struct Run<const C: usize> {
    pub radiance: Vec<[f64; C]>,
    pub iterations: u32,
    pub residual: f64,
    pub residual_history: Vec<f64>,
    pub converged: bool,
}

/// Solve the system with the given settings.
pub fn solve(system: &System, settings: &Settings) -> Result<Solution> {
    settings.validate()?;
    let n = system.len();
    if system.emission_norm() == 0.0 {
        return Ok(Solution {
            radiance: vec![[0.0; 3]; n],
            iterations: 0,
            residual: 0.0,
            residual_history: vec![],
            converged: true,
            grey: false,
            omega: 1.0,
            method: settings.method,
        });
    }
    if settings.method != Method::Neumann {
        check_not_singular(system)?;
    }
    let grey = (0..n).all(|i| {
        let (r, e) = (system.reflectance[i], system.emission[i]);
        r[0] == r[1] && r[1] == r[2] && e[0] == e[1] && e[1] == e[2]
    });
    let mut settings = *settings;
    let auto = settings.method == Method::GaussSeidel && settings.omega.is_none();
    if auto {
        settings.omega = Some(auto_omega(system));
    }
    let result = solve_as_given(system, &settings, grey);
    match result {
        Err(Error::Numerical(_)) if auto && settings.omega != Some(1.0) => {
            settings.omega = Some(1.0);
            solve_as_given(system, &settings, grey)
        }
        other => other,
    }
}

fn solve_as_given(system: &System, settings: &Settings, grey: bool) -> Result<Solution> {
    if grey {
        let problem = Problem::<1> {
            system,
            rho: system.reflectance.iter().map(|r| [r[0]]).collect(),
            e: system.emission.iter().map(|e| [e[0]]).collect(),
        };
        let run = dispatch(&problem, settings)?;
        Ok(finish(run, |x| [x[0]; 3], true, settings))
    } else {
        let problem = Problem::<3> {
            system,
            rho: system.reflectance.to_vec(),
            e: system.emission.to_vec(),
        };
        let run = dispatch(&problem, settings)?;
        Ok(finish(run, |x| x, false, settings))
    }
}

fn dispatch<const C: usize>(problem: &Problem<C>, settings: &Settings) -> Result<Run<C>> {
    let _progress = crate::progress::stage(&format!("solve ({})", settings.method.name()), None);
    let run = match settings.method {
        Method::Neumann => stationary::neumann(problem, settings.bounces),
        Method::Jacobi => stationary::jacobi(problem, settings),
        Method::GaussSeidel => stationary::gauss_seidel(problem, settings),
        Method::Cg => cg::solve(problem, settings)?,
        Method::Southwell => southwell::solve(problem, settings),
    };
    if !run.residual.is_finite() || run.radiance.iter().flatten().any(|x| !x.is_finite()) {
        return Err(Error::Numerical(format!(
            "the {} solver diverged (residual {:e} after {} iterations){}",
            settings.method.name(),
            run.residual,
            run.iterations,
            match settings.omega {
                Some(w) if settings.method == Method::GaussSeidel && w > 1.0 => {
                    format!("; over-relaxation ω = {w} is too large here, try 1")
                }
                _ => String::new(),
            }
        )));
    }
    Ok(run)
}

fn finish<const C: usize>(
    run: Run<C>,
    widen: impl Fn([f64; C]) -> Rgb,
    grey: bool,
    settings: &Settings,
) -> Solution {
    let mut radiance: Vec<Rgb> = run.radiance.into_iter().map(widen).collect();
    crate::bake::clamp_rounding(&mut radiance);
    Solution {
        omega: match settings.method {
            Method::GaussSeidel => settings.omega.unwrap_or(1.0),
            _ => 1.0,
        },
        radiance,
        iterations: run.iterations,
        residual: run.residual,
        residual_history: run.residual_history,
        converged: run.converged,
        grey,
        method: settings.method,
    }
}

/// Detects, before iterating, the singular case ρ = 1 in a closed enclosure: for some channel
/// a non-empty set S of patches with ρ = 1, each with Σ_j F_ij ≥ 1 − the estimator's
/// [`crate::form_factor::FormFactors::closed_row_tolerance`]
/// and gathering only from patches of S. Then K restricted to S is (row-)stochastic, 1 is an
/// eigenvalue of K, I − K is singular, and light emitted into S would bounce forever (no
/// finite solution; the iteration would grow without bound or stall). S is found as the
/// largest such set by elimination: start from every ρ = 1 patch with a full row and remove,
/// transitively, every patch that gathers from a patch outside S (a work list over Fᵀ, O(nnz)).
/// The error is [`Error::Numerical`] saying which channel and how many patches.
///
/// The Neumann series with a finite bounce count is well defined for any ρ and is not checked.
pub fn check_not_singular(system: &System) -> Result<()> {
    let full_rho = |c: usize| system.reflectance.iter().any(|r| r[c] >= 1.0);
    if !(0..3).any(full_rho) {
        return Ok(());
    }
    let n = system.len();
    let row_sums = system.form_factors.row_sums();
    let tolerance = system.form_factors.closed_row_tolerance;
    let transpose = system.form_factors.matrix.transpose_view().to_csr();
    for c in 0..3 {
        let candidates = (0..n)
            .map(|i| system.reflectance[i][c] >= 1.0 && row_sums[i] >= 1.0 - tolerance)
            .collect();
        // Row j of Fᵀ lists the patches i that gather from j (F_ij > 0).
        let count = closed_full_set(candidates, |j, gatherer| {
            if let Some(row) = transpose.outer_view(j) {
                row.iter()
                    .filter(|(_, &f)| f > 0.0)
                    .for_each(|(i, _)| gatherer(i));
            }
        });
        if count > 0 {
            return Err(singular(count, c, "patches"));
        }
    }
    Ok(())
}

/// The size of the largest set S of the `candidates` (patches with ρ = 1 in one channel and a
/// full row) none of which gathers from a patch outside S, given the patches that gather from
/// each patch j (`gatherers(j, f)` calls `f(i)` for each i with F_ij > 0): by elimination,
/// starting from every candidate and removing, transitively, every one that gathers from a
/// patch outside S (a work list, O(nnz)). K restricted to a non-empty S is stochastic: the
/// system is singular ([`check_not_singular`], and the hierarchical method's own check).
pub fn closed_full_set(
    mut in_s: Vec<bool>,
    gatherers: impl Fn(usize, &mut dyn FnMut(usize)),
) -> usize {
    let mut queue: Vec<usize> = (0..in_s.len()).filter(|&j| !in_s[j]).collect();
    while let Some(j) = queue.pop() {
        gatherers(j, &mut |i| {
            if in_s[i] {
                in_s[i] = false;
                queue.push(i);
            }
        });
    }
    in_s.iter().filter(|&&x| x).count()
}

/// The error of a singular system: `count` `what` (patches, roots) with ρ = 1 in `channel`
/// (0 red, 1 green, 2 blue) closed among themselves ([`closed_full_set`]).
pub fn singular(count: usize, channel: usize, what: &str) -> Error {
    const CHANNELS: [&str; 3] = ["red", "green", "blue"];
    Error::Numerical(format!(
        "the system is singular and has no solution: {count} {what} with reflectance ρ = 1 in \
         the {} channel (MTL Kd) form a closed enclosure (their form factors sum to 1 and they \
         see only each other), so light bounces among them forever without being absorbed. \
         Lower Kd below 1 (real materials reflect at most ~0.95) or open the enclosure",
        CHANNELS[channel]
    ))
}

#[cfg(test)]
mod tests;
