//! Solving (I − K) L = E for the patch radiance L, per RGB channel (three channels share each
//! pass over F). Three methods, one entry point [`solve`]:
//!
//! - **Neumann** (`--bounces N`): L = Σ_{b=0}^{N} K^b E exactly; term b is the light after b
//!   bounces, so N = 1 is direct illumination (emission plus one reflection).
//! - **Jacobi**: L⁽ᵏ⁺¹⁾ = E + K L⁽ᵏ⁾ from L⁽⁰⁾ = E. Its iterates are the Neumann partial sums
//!   (L⁽ᴺ⁾ = Σ_{b≤N} K^b E), and since E − (I − K)L⁽ᵏ⁾ = L⁽ᵏ⁺¹⁾ − L⁽ᵏ⁾ the residual costs
//!   nothing extra. Converges because ‖K‖∞ ≤ max ρ · max row sum < 1 (Cohen & Wallace §5.3).
//! - **Gauss–Seidel**: the same update, in place, row by row (uses the newest values):
//!   typically about half the sweeps of Jacobi for the same tolerance.
//!
//! The iterative methods stop when the relative residual ‖E − (I − K)L‖₂ / ‖E‖₂ ≤ tolerance or
//! after `max_iterations` sweeps; [`Solution::converged`] says which, and the caller must not
//! hide it.

use serde::Serialize;

use crate::matrix::{norm, Rgb, System};
use crate::{Error, Result};

/// The solution method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Jacobi iteration from L = E.
    Jacobi,
    /// Gauss–Seidel iteration, in place.
    GaussSeidel,
    /// Truncated Neumann series E + KE + … + K^N E (N = `bounces`).
    Neumann,
}

impl Method {
    /// The method's command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Jacobi => "jacobi",
            Method::GaussSeidel => "gauss-seidel",
            Method::Neumann => "neumann",
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Settings {
    /// The method.
    pub method: Method,
    /// Relative residual at which Jacobi and Gauss–Seidel stop; > 0.
    pub tolerance: f64,
    /// Sweep limit of Jacobi and Gauss–Seidel; ≥ 1.
    pub max_iterations: u32,
    /// Number of bounces N of the Neumann series.
    pub bounces: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::GaussSeidel,
            tolerance: 1e-6,
            max_iterations: 10_000,
            bounces: 1,
        }
    }
}

impl Settings {
    /// Check ranges before any work.
    pub fn validate(&self) -> Result<()> {
        if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
            return Err(Error::usage(
                "--tolerance",
                format!("{} is not a positive number", self.tolerance),
            ));
        }
        if self.max_iterations == 0 {
            return Err(Error::usage("--max-iterations", "must be at least 1"));
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
    /// Sweeps (Jacobi, Gauss–Seidel) or bounces (Neumann) performed.
    pub iterations: u32,
    /// Final relative residual ‖E − (I − K)L‖₂ / ‖E‖₂ of the returned L.
    pub residual: f64,
    /// Relative residual per sweep: for Gauss–Seidel after sweep k; for Jacobi of the iterate
    /// each sweep started from (free, see the module docs); for Neumann the final one.
    pub residual_history: Vec<f64>,
    /// False when an iterative method hit `max_iterations` above the tolerance.
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
        });
    }
    if settings.method != Method::Neumann {
        check_not_singular(system)?;
    }
    match settings.method {
        Method::Neumann => Ok(neumann(system, settings.bounces)),
        Method::Jacobi => Ok(jacobi(system, settings)),
        Method::GaussSeidel => Ok(gauss_seidel(system, settings)),
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
    const CHANNELS: [&str; 3] = ["red", "green", "blue"];
    let full_rho = |c: usize| system.reflectance.iter().any(|r| r[c] >= 1.0);
    if !(0..3).any(full_rho) {
        return Ok(());
    }
    let n = system.len();
    let row_sums = system.form_factors.row_sums();
    let tolerance = system.form_factors.closed_row_tolerance;
    let transpose = system.form_factors.matrix.transpose_view().to_csr();
    for (c, channel) in CHANNELS.iter().enumerate() {
        let mut in_s: Vec<bool> = (0..n)
            .map(|i| system.reflectance[i][c] >= 1.0 && row_sums[i] >= 1.0 - tolerance)
            .collect();
        let mut queue: Vec<usize> = (0..n).filter(|&j| !in_s[j]).collect();
        while let Some(j) = queue.pop() {
            // Row j of Fᵀ lists the patches i that gather from j (F_ij > 0).
            if let Some(gatherers) = transpose.outer_view(j) {
                for (i, &f) in gatherers.iter() {
                    if f > 0.0 && in_s[i] {
                        in_s[i] = false;
                        queue.push(i);
                    }
                }
            }
        }
        let count = in_s.iter().filter(|&&x| x).count();
        if count > 0 {
            return Err(Error::Numerical(format!(
                "the system is singular and has no solution: {count} patches with reflectance \
                 ρ = 1 in the {channel} channel (MTL Kd) form a closed enclosure (their form \
                 factors sum to 1 and they see only each other), so light bounces among them \
                 forever without being absorbed. Lower Kd below 1 (real materials reflect at \
                 most ~0.95) or open the enclosure"
            )));
        }
    }
    Ok(())
}

/// E + KE + … + K^N E.
fn neumann(system: &System, bounces: u32) -> Solution {
    let mut l = system.emission.to_vec();
    let mut term = l.clone();
    let mut next = vec![[0.0; 3]; l.len()];
    for _ in 0..bounces {
        system.apply_k(&term, &mut next);
        std::mem::swap(&mut term, &mut next);
        for (li, ti) in l.iter_mut().zip(&term) {
            for c in 0..3 {
                li[c] += ti[c];
            }
        }
    }
    let residual = system.relative_residual(&l);
    Solution {
        radiance: l,
        iterations: bounces,
        residual,
        residual_history: vec![residual],
        converged: true,
    }
}

fn jacobi(system: &System, settings: &Settings) -> Solution {
    let e_norm = system.emission_norm();
    let mut l = system.emission.to_vec();
    let mut next = vec![[0.0; 3]; l.len()];
    let mut history = Vec::new();
    let mut iterations = 0;
    let mut converged = false;
    while iterations < settings.max_iterations {
        // next = E + K l; and E − (I − K) l = next − l.
        system.apply_k(&l, &mut next);
        for (x, e) in next.iter_mut().zip(system.emission) {
            for c in 0..3 {
                x[c] += e[c];
            }
        }
        let diff: Vec<Rgb> = next
            .iter()
            .zip(&l)
            .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
            .collect();
        std::mem::swap(&mut l, &mut next);
        iterations += 1;
        // Residual of the iterate just replaced; the new iterate's is ≤ ‖K‖ times smaller.
        let r_prev = norm(&diff) / e_norm;
        history.push(r_prev);
        if r_prev <= settings.tolerance {
            converged = true;
            break;
        }
    }
    let residual = system.relative_residual(&l);
    Solution {
        radiance: l,
        iterations,
        residual,
        residual_history: history,
        converged: converged || residual <= settings.tolerance,
    }
}

fn gauss_seidel(system: &System, settings: &Settings) -> Solution {
    let mut l = system.emission.to_vec();
    let mut history = Vec::new();
    let mut iterations = 0;
    let mut converged = false;
    let mut residual = system.relative_residual(&l);
    while iterations < settings.max_iterations {
        for i in 0..l.len() {
            let g = system.gather(i, &l);
            let (e, r) = (system.emission[i], system.reflectance[i]);
            l[i] = [e[0] + r[0] * g[0], e[1] + r[1] * g[1], e[2] + r[2] * g[2]];
        }
        iterations += 1;
        residual = system.relative_residual(&l);
        history.push(residual);
        if residual <= settings.tolerance {
            converged = true;
            break;
        }
    }
    Solution {
        radiance: l,
        iterations,
        residual,
        residual_history: history,
        converged,
    }
}
