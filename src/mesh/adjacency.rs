//! Mesh adjacency shared by the normals and the bake: the faces around each vertex, and the
//! grouping of faces that belong together (union–find over a relation).

/// The faces around each vertex of a triangle mesh (compressed: offsets + one list), each
/// vertex's faces in increasing order.
pub(crate) struct VertexFaces {
    offsets: Vec<usize>,
    faces: Vec<u32>,
}

impl VertexFaces {
    /// Corners equal to `u32::MAX` are left out (a triangle to be skipped).
    pub(crate) fn new(triangles: &[[u32; 3]], vertices: usize) -> Self {
        let mut offsets = vec![0usize; vertices + 1];
        for t in triangles {
            for &v in t.iter().filter(|&&v| v != u32::MAX) {
                offsets[v as usize + 1] += 1;
            }
        }
        for v in 0..vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut faces = vec![0u32; offsets[vertices]];
        let mut fill = offsets.clone();
        for (f, t) in triangles.iter().enumerate() {
            for &v in t.iter().filter(|&&v| v != u32::MAX) {
                faces[fill[v as usize]] = f as u32;
                fill[v as usize] += 1;
            }
        }
        VertexFaces { offsets, faces }
    }

    /// The faces at vertex `v`.
    pub(crate) fn faces(&self, v: usize) -> &[u32] {
        &self.faces[self.offsets[v]..self.offsets[v + 1]]
    }

    /// Where vertex `v`'s faces start in the flat list (slot of its first face).
    pub(crate) fn offset(&self, v: usize) -> usize {
        self.offsets[v]
    }

    /// Total number of (vertex, face) incidences.
    pub(crate) fn len(&self) -> usize {
        self.faces.len()
    }
}

/// Partition `0..n` into the connected components of the relation `joined` (union–find);
/// returns a group label per element, labels numbered in order of each group's first member
/// (deterministic).
pub(crate) fn groups(n: usize, joined: impl Fn(usize, usize) -> bool) -> Vec<usize> {
    fn find(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    let mut parent: Vec<usize> = (0..n).collect();
    for a in 0..n {
        for b in a + 1..n {
            if joined(a, b) {
                let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                if ra != rb {
                    parent[ra.max(rb)] = ra.min(rb);
                }
            }
        }
    }
    let mut label = vec![usize::MAX; n];
    let mut next = 0;
    (0..n)
        .map(|a| {
            let r = find(&mut parent, a);
            if label[r] == usize::MAX {
                label[r] = next;
                next += 1;
            }
            label[r]
        })
        .collect()
}
