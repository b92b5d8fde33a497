//! Twins: a triangle and its reverse over the same corners, the two sides of one surface,
//! found by their corners' bits (see the module documentation of [`super`]).

use std::collections::HashMap;

use glam::Vec3A;

use crate::geometry::winding_key;

/// Twin pairing of canonical triangles (see the module documentation): for each triangle, its
/// twin's position in `tris` and which of its own corners each corner of the *later* of the two
/// is (`corners[k]` = the earlier triangle's corner that is the later one's corner `k`), or
/// `None`. Symmetric: if `k` pairs with `j`, `j` pairs with `k` (with the same `corners`).
pub(super) fn pair_twins(tris: &[[Vec3A; 3]]) -> Vec<Option<(usize, [u8; 3])>> {
    // Corner bits with −0.0 made +0.0, so the two sides of one surface always match.
    let bits = |p: Vec3A| (p + Vec3A::ZERO).to_array().map(f32::to_bits);
    // (sorted corners, parity of the sort) of each triangle: twins have the same corners and
    // opposite parity (a reversed triangle is an odd permutation of the original's corners).
    let keyed: Vec<([[u32; 3]; 3], bool)> = tris.iter().map(|t| winding_key(t.map(bits))).collect();
    // Corner sets that occur more than once, each with its triangles in input order. One hash
    // insert per triangle; map iteration order is never used, so nothing depends on hashing.
    let mut first: HashMap<[[u32; 3]; 3], usize> = HashMap::with_capacity(tris.len());
    let mut group_of_first: HashMap<usize, usize> = HashMap::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (k, (corners, _)) in keyed.iter().enumerate() {
        let f = *first.entry(*corners).or_insert(k);
        if f != k {
            let g = *group_of_first.entry(f).or_insert_with(|| {
                groups.push(vec![f]);
                groups.len() - 1
            });
            groups[g].push(k);
        }
    }
    let mut pairs = vec![None; tris.len()];
    for group in &groups {
        // Each member pairs with the earliest unpaired member of the opposite winding.
        let mut waiting: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
        for &k in group {
            let odd = keyed[k].1 as usize;
            if waiting[1 - odd].is_empty() {
                waiting[odd].push(k);
                continue;
            }
            let j = waiting[1 - odd].remove(0);
            let earlier = tris[j].map(bits);
            let later = tris[k].map(bits);
            let map = later.map(|c| earlier.iter().position(|&e| e == c).unwrap_or(0) as u8);
            pairs[j] = Some((k, map));
            pairs[k] = Some((j, map));
        }
    }
    pairs
}
