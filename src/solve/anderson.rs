//! Anderson acceleration of a fixed-point iteration x ← T(x) (Anderson, "Iterative procedures
//! for nonlinear integral equations", J. ACM 12(4), 1965; in the form of Walker & Ni,
//! "Anderson acceleration for fixed-point iterations", SIAM J. Numer. Anal. 49(4), 2011).
//!
//! Step k has the iterate x_k, its image g_k = T(x_k) and residual f_k = g_k − x_k. With the
//! last m differences ΔF = [f_{i+1} − f_i] and ΔG = [g_{i+1} − g_i], γ minimises
//! ‖f_k − ΔF γ‖_W (W a weight per entry: an element's area) and the next iterate is
//! x_{k+1} = g_k − ΔG γ: the combination of the last m + 1 images whose residuals, combined
//! alike, are smallest. With m = 0 it is the plain iteration x_{k+1} = g_k.
//!
//! Why it pays for radiosity: a sweep is the affine map T(x) = E + Kx, and for an affine map
//! Anderson acceleration of unlimited depth is essentially GMRES on (I − K)x = E (Walker & Ni
//! §4). The plain sweep's residual falls by ρ(K) per sweep (ρ·max row sum: 0.9 in a white
//! room, hundreds of sweeps to 10⁻⁶); a Krylov method's by about (√κ − 1)/(√κ + 1),
//! κ = (1 + ρ)/(1 − ρ), where K is similar to a symmetric matrix (reciprocity; see [`super::cg`]):
//! 0.63 per sweep at ρ = 0.9. A short memory (m = [`DEPTH`]) keeps most of that.
//!
//! The differences and the previous residual are kept in f32 (at 10⁶ elements each vector is
//! 12 MB, not 24): a difference's own relative precision is what the least-squares fit
//! needs. The previous image, from which ΔG is taken, stays in f64: near convergence ΔG is
//! a millionth of it. The small normal equations (m × m) are solved by Cholesky with a
//! ridge of 10⁻¹⁰ of their largest diagonal entry, which keeps them solvable where the
//! columns are nearly dependent; where they still cannot be solved (a history that is not
//! finite) the oldest column is dropped. Every sum is taken in fixed chunks in a fixed
//! order: the same iterates for any thread count.

use std::collections::VecDeque;

use nalgebra::{DMatrix, DVector};

use super::cg::sum;
use crate::color::Rgb;

/// Differences kept: the acceleration's memory m.
pub const DEPTH: usize = 3;

/// The ridge added to the normal equations' diagonal, relative to their largest diagonal
/// entry: nearly dependent columns share a bounded weight instead of an arbitrary one.
const RIDGE: f64 = 1e-10;

/// The state of an accelerated iteration over `weights.len()` entries of three channels.
pub struct Anderson {
    depth: usize,
    weights: Vec<f64>,
    /// The previous step's residual f (f32) and image g (f64), if any.
    previous: Option<(Vec<[f32; 3]>, Vec<Rgb>)>,
    /// The last differences ΔF, ΔG, oldest first.
    df: VecDeque<Vec<[f32; 3]>>,
    dg: VecDeque<Vec<[f32; 3]>>,
}

impl Anderson {
    /// An iteration over entries of weight `weights` (≥ 0; 0 leaves an entry out of the fit,
    /// though it is still combined) keeping `depth` differences.
    pub fn new(depth: usize, weights: Vec<f64>) -> Anderson {
        Anderson {
            depth,
            weights,
            previous: None,
            df: VecDeque::new(),
            dg: VecDeque::new(),
        }
    }

    /// Forgets the history: the next step is a plain one.
    pub fn restart(&mut self) {
        self.previous = None;
        self.df.clear();
        self.dg.clear();
    }

    /// The next iterate from the iterate `x` and its image `g` = T(`x`) (equal lengths, that
    /// of the weights), written over `g`; false if it is `g` itself (no history: the first
    /// step, or the first after [`Anderson::restart`]).
    pub fn step(&mut self, x: &[Rgb], g: &mut [Rgb]) -> bool {
        let n = self.weights.len();
        assert!(x.len() == n && g.len() == n, "Anderson: lengths differ");
        if self.depth == 0 {
            return false;
        }
        let f = |i: usize| -> Rgb { std::array::from_fn(|c| g[i][c] - x[i][c]) };
        // The new differences, in the oldest's buffers once the history is full.
        let (mut pf, mut pg) = match self.previous.take() {
            None => (vec![[0.0; 3]; n], vec![[0.0; 3]; n]),
            Some((pf, pg)) => {
                let (mut df, mut dg) = if self.df.len() == self.depth {
                    (self.df.pop_front().unwrap(), self.dg.pop_front().unwrap())
                } else {
                    (vec![[0.0; 3]; n], vec![[0.0; 3]; n])
                };
                for i in 0..n {
                    let fi = f(i);
                    for c in 0..3 {
                        df[i][c] = (fi[c] - pf[i][c] as f64) as f32;
                        dg[i][c] = (g[i][c] - pg[i][c]) as f32;
                    }
                }
                self.df.push_back(df);
                self.dg.push_back(dg);
                (pf, pg)
            }
        };
        for (i, p) in pf.iter_mut().enumerate() {
            *p = f(i).map(|v| v as f32);
        }
        pg.copy_from_slice(g);
        self.previous = Some((pf, pg));
        while !self.df.is_empty() {
            if let Some(gamma) = self.fit(x, g) {
                for (j, dg) in self.dg.iter().enumerate() {
                    for (gi, d) in g.iter_mut().zip(dg) {
                        for c in 0..3 {
                            gi[c] -= gamma[j] * d[c] as f64;
                        }
                    }
                }
                return true;
            }
            self.df.pop_front();
            self.dg.pop_front();
        }
        false
    }

    /// γ minimising ‖f − ΔF γ‖_W (f = `g` − `x`) by the ridged normal equations, or `None`
    /// where they cannot be solved (a history of zeros or of values that are not finite).
    fn fit(&self, x: &[Rgb], g: &[Rgb]) -> Option<DVector<f64>> {
        let m = self.df.len();
        let w = &self.weights;
        let dot = |a: &(dyn Fn(usize) -> Rgb + Sync), b: &(dyn Fn(usize) -> Rgb + Sync)| -> f64 {
            let [s] = sum(w.len(), |i| {
                let (a, b) = (a(i), b(i));
                [w[i] * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])]
            });
            s
        };
        let col = |j: usize| {
            let d = &self.df[j];
            move |i: usize| -> Rgb { std::array::from_fn(|c| d[i][c] as f64) }
        };
        let mut a = DMatrix::zeros(m, m);
        let mut b = DVector::zeros(m);
        for j in 0..m {
            let cj = col(j);
            for k in 0..=j {
                let ck = col(k);
                a[(j, k)] = dot(&cj, &ck);
                a[(k, j)] = a[(j, k)];
            }
            b[j] = dot(&cj, &|i| std::array::from_fn(|c| g[i][c] - x[i][c]));
        }
        let scale = (0..m).map(|j| a[(j, j)]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        for j in 0..m {
            a[(j, j)] += RIDGE * scale;
        }
        let gamma = a.cholesky()?.solve(&b);
        gamma.iter().all(|v| v.is_finite()).then_some(gamma)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// A random affine map x ↦ E + Kx with K = ρ·F, F the form factors of a closed scene
    /// of `n` patches: S symmetric and random, the areas its row sums, F = diag(1/A)·S, so
    /// that every row of F sums to 1 and A_i F_ij = A_j F_ji (reciprocity). K's spectral
    /// radius is then ρ (the uniform vector).
    fn system(n: usize, rho: f64, seed: u64) -> (DMatrix<f64>, Vec<Rgb>, Vec<f64>) {
        let mut rng = Rng::new(&[seed]);
        let mut s = DMatrix::zeros(n, n);
        for i in 0..n {
            for j in 0..i {
                let v = rng.next_f64().powi(3);
                s[(i, j)] = v;
                s[(j, i)] = v;
            }
        }
        let areas: Vec<f64> = (0..n).map(|i| s.row(i).sum()).collect();
        let k = DMatrix::from_fn(n, n, |i, j| rho * s[(i, j)] / areas[i]);
        let e: Vec<Rgb> = (0..n)
            .map(|i| {
                if i % 7 == 0 {
                    [1.0, 0.5, 0.25]
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        (k, e, areas)
    }

    fn apply(k: &DMatrix<f64>, e: &[Rgb], x: &[Rgb]) -> Vec<Rgb> {
        (0..e.len())
            .map(|i| {
                std::array::from_fn(|c| {
                    e[i][c] + (0..e.len()).map(|j| k[(i, j)] * x[j][c]).sum::<f64>()
                })
            })
            .collect()
    }

    /// Sweeps (and the final iterate) to a relative residual of 1e-10.
    fn run(depth: usize, k: &DMatrix<f64>, e: &[Rgb], areas: &[f64]) -> (usize, Vec<Rgb>) {
        let mut aa = Anderson::new(depth, areas.to_vec());
        let norm = |v: &[Rgb]| {
            v.iter()
                .zip(areas)
                .map(|(v, a)| a * v.iter().map(|x| x * x).sum::<f64>())
                .sum::<f64>()
                .sqrt()
        };
        let mut x = e.to_vec();
        for sweep in 1..=5000 {
            let mut g = apply(k, e, &x);
            let f: Vec<Rgb> = g
                .iter()
                .zip(&x)
                .map(|(g, x)| std::array::from_fn(|c| g[c] - x[c]))
                .collect();
            if norm(&f) <= 1e-10 * norm(e) {
                return (sweep, g);
            }
            aa.step(&x, &mut g);
            x = g;
        }
        panic!("no convergence in 5000 sweeps");
    }

    /// The accelerated iteration reaches the dense direct solve's answer, in far fewer
    /// sweeps than the plain one where the reflectance is high: the plain sweep's residual
    /// falls by K's spectral radius ρ = 0.95 per sweep (about 430 sweeps to 1e-10), a
    /// Krylov method's by at most (√κ − 1)/(√κ + 1) = 0.73 at κ = 39 (about 75; about 20 here,
    /// where a random F's other eigenvalues are small).
    #[test]
    fn accelerated_sweeps_reach_the_direct_solution_in_a_fraction_of_the_sweeps() {
        let (k, e, areas) = system(60, 0.95, 3);
        let direct = (DMatrix::identity(60, 60) - &k)
            .lu()
            .solve(&DMatrix::from_fn(60, 3, |i, c| e[i][c]))
            .unwrap();
        let (plain, _) = run(0, &k, &e, &areas);
        let (fast, x) = run(DEPTH, &k, &e, &areas);
        for i in 0..60 {
            for c in 0..3 {
                // 1e-10 relative residual, amplified at most 1/(1 − 0.95) = 20 times.
                assert!(
                    (x[i][c] - direct[(i, c)]).abs() <= 1e-8 * direct.max(),
                    "entry {i}, channel {c}: {} against {}",
                    x[i][c],
                    direct[(i, c)]
                );
            }
        }
        assert!(plain > 300, "the plain iteration took only {plain} sweeps");
        assert!(
            3 * fast < plain,
            "accelerated {fast} sweeps against the plain {plain}"
        );
    }

    /// A depth of 0 is the plain iteration, image for image.
    #[test]
    fn depth_zero_is_the_plain_iteration() {
        let (k, e, areas) = system(20, 0.8, 5);
        let mut aa = Anderson::new(0, areas);
        let x = e.clone();
        let g = apply(&k, &e, &x);
        let mut stepped = g.clone();
        assert!(!aa.step(&x, &mut stepped));
        assert_eq!(stepped, g);
    }
}
