//! The receivers' quadrature rule: the points at which an element gathers its links' light
//! (and where burial under contact geometry is tested), their weights with the buried points
//! left out, and systematic sampling by weight. Links ([`super::links`]), the tree
//! ([`super::tree`]), the elements' direct light ([`super::direct`]) and the leaves' final
//! gather ([`super::regather`]) all integrate over an element with it.

use std::sync::OnceLock;

use crate::sampling::gauss_rule;

/// Points of the rule that element receivers integrate with: the symmetric Gauss rule of
/// degree 5 (7 points). Its points are also where burial is tested. The 3-point rule (degree
/// 2) leaves large receivers low against the path-traced surface means (the Cornell box's
/// floor and ceiling at a fine ε): its interior points underestimate the convex fall-off of
/// the kernel. Degree 5 takes most of that out; the 12-point rule of degree 6 gives the same
/// answers for more time.
pub const RECEIVER_POINTS: usize = 7;

/// The receivers' quadrature rule ([`RECEIVER_POINTS`] points, weights summing to 1).
pub fn receiver_rule() -> &'static [([f64; 3], f64)] {
    static RULE: OnceLock<Vec<([f64; 3], f64)>> = OnceLock::new();
    RULE.get_or_init(|| gauss_rule(RECEIVER_POINTS).expect("a rule of RECEIVER_POINTS exists"))
}

/// The receiver rule's weights with the points buried in `buried` (bit k for point k) set
/// to 0: they sum to the element's visible fraction.
pub fn unburied_weights(buried: u16) -> [f64; RECEIVER_POINTS] {
    let rule = receiver_rule();
    std::array::from_fn(|k| {
        if buried & (1 << k) == 0 {
            rule[k].1
        } else {
            0.0
        }
    })
}

/// Which receiver-rule points of each element are buried (bit k for point k of
/// [`receiver_rule`]) and each element's visible fraction, both indexed by element; empty
/// slices (the default) mean nothing is buried.
#[derive(Clone, Copy, Debug, Default)]
pub struct Burial<'a> {
    pub buried: &'a [u16],
    pub visible: &'a [f64],
}

impl Burial<'_> {
    /// Element `e`'s buried rule points.
    pub fn mask(&self, e: usize) -> u16 {
        self.buried.get(e).copied().unwrap_or(0)
    }

    /// Element `e`'s visible fraction in [0, 1].
    pub fn visible(&self, e: usize) -> f64 {
        self.visible.get(e).copied().unwrap_or(1.0)
    }
}

/// `n` indices drawn with probability ∝ `weights` by systematic sampling (one uniform `u` in
/// [0, 1) offsets n evenly spaced positions on the cumulative weights); `None` when every
/// weight is 0.
pub fn pick_proportional(weights: &[f64], n: usize, u: f64) -> Option<Vec<usize>> {
    let total: f64 = weights.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let step = total / n as f64;
    let mut picks = Vec::with_capacity(n);
    let (mut k, mut cumulative) = (0, weights[0]);
    for i in 0..n {
        let at = (u + i as f64) * step;
        while at >= cumulative && k + 1 < weights.len() {
            k += 1;
            cumulative += weights[k];
        }
        // Skip zero weights the rounding of `cumulative` might land on.
        while weights[k] == 0.0 && k > 0 {
            k -= 1;
        }
        picks.push(k);
    }
    Some(picks)
}
