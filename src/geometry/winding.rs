//! Winding keys: how a triangle and its reverse over the same corners (the two sides of one
//! surface, *twins*) are recognised, by one rule for vertex indices ([`crate::scene`]'s
//! two-sided faces) and for corner bits ([`crate::visibility`]'s twin pairing).

/// A triangle's corners sorted, with the parity of the sort: a triangle and its reverse over
/// the same corners (twins) have the same sorted corners and opposite parity, since a reversed
/// triangle is an odd permutation of the original's corners. Used on vertex indices by
/// [`crate::scene`] and on corner bits by [`crate::visibility`], so the two recognise twins by one
/// rule.
pub fn winding_key<T: PartialOrd + Copy>(corners: [T; 3]) -> ([T; 3], bool) {
    let mut c = corners;
    let mut odd = false;
    for (a, b) in [(0, 1), (1, 2), (0, 1)] {
        if c[a] > c[b] {
            c.swap(a, b);
            odd = !odd;
        }
    }
    (c, odd)
}
