//! The two hierarchies of the hierarchical solver: element trees (each root patch is the root of
//! a quadtree of triangles, split 1 → 4 at the edge midpoints) and the cluster tree over the
//! root patches (a binary BVH, median split on the longest axis), whose root stands for the
//! whole scene. A [`Node`] names either kind. This module owns their geometry and sampling, not
//! their radiance or links.

use glam::DVec3;

use crate::mesh::Patches;
use crate::sampling::{stratified_triangle_barycentrics, Rng};

/// "No element" in [`Element::first_child`].
pub const NO_CHILD: u32 = u32::MAX;

/// Root patches per leaf cluster, at most. Small enough that opening a leaf cluster's self-link
/// (all pairs of its root patches) costs little; large enough to halve the cluster count.
pub const LEAF_SIZE: usize = 4;

/// A point [`Tree::sample`] drew on a node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// The element it lies on (a root element when the node is a cluster).
    pub element: usize,
    /// Its barycentric coordinates on that element's corners.
    pub at: [f64; 3],
    /// Which part of the node it lies in: on an element, the quarter [`Tree::split`] makes
    /// ([`quarter_of`]); in a cluster, an index among [`Tree::parts`].
    pub part: u8,
}

/// At most this many [`Tree::parts`] of a cluster: a leaf cluster's at most [`LEAF_SIZE`]
/// root elements, or an inner cluster's two children's children (2 each for inner clusters,
/// at most [`LEAF_SIZE`] for leaves).
pub const MAX_PARTS: usize = 2 * LEAF_SIZE;

/// The child of an element that [`Tree::split`] makes holding the point with barycentrics
/// `b` (on the corners a, b, c): 0, 1 or 2 at the corner whose coordinate is at least ½, 3
/// for the middle triangle.
pub fn quarter_of(b: [f64; 3]) -> u8 {
    (0..3).find(|&k| b[k] >= 0.5).unwrap_or(3) as u8
}

/// A node of either hierarchy: an element (index into [`Tree::elements`]) or a cluster (index
/// into [`Tree::clusters`], tagged by the top bit). Elements sort before clusters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Node(u32);

const CLUSTER_BIT: u32 = 1 << 31;

impl Node {
    /// Element `i`.
    pub fn element(i: usize) -> Node {
        debug_assert!((i as u64) < CLUSTER_BIT as u64);
        Node(i as u32)
    }

    /// Cluster `i`.
    pub fn cluster(i: usize) -> Node {
        debug_assert!((i as u64) < CLUSTER_BIT as u64);
        Node(i as u32 | CLUSTER_BIT)
    }

    /// The element's index, if this is an element.
    pub fn as_element(self) -> Option<usize> {
        (self.0 & CLUSTER_BIT == 0).then_some(self.0 as usize)
    }

    /// The cluster's index, if this is a cluster.
    pub fn as_cluster(self) -> Option<usize> {
        (self.0 & CLUSTER_BIT != 0).then_some((self.0 & !CLUSTER_BIT) as usize)
    }

    /// The node whose [`Node::raw`] is `raw`.
    pub fn from_raw(raw: u32) -> Node {
        Node(raw)
    }

    /// The 32 bits that are the node (what ranks exchange; the order of nodes is theirs).
    pub fn raw(self) -> u32 {
        self.0
    }

    /// The raw id (a key for seeding per-link random numbers).
    pub fn id(self) -> u64 {
        self.0 as u64
    }
}

/// A triangle of an element tree. Its material is its root patch's.
#[derive(Clone, Debug)]
pub struct Element {
    /// Vertex indices into [`Tree::positions`], counter-clockwise seen from the front.
    pub vertices: [u32; 3],
    /// Smooth-surface normals at the corners (not unit; see [`Patches::corner_normal`]).
    pub corner_normals: [DVec3; 3],
    /// Unit normal of the flat triangle.
    pub normal: DVec3,
    /// Centroid, scene units.
    pub centroid: DVec3,
    /// Largest distance from the centroid to a corner, scene units.
    pub radius: f64,
    /// Area, scene units squared; > 0.
    pub area: f64,
    /// The root patch this element was cut from (its material, and its triangle in the
    /// visibility BVH).
    pub root: u32,
    /// Index of the first of four children (consecutive), or [`NO_CHILD`] for a leaf.
    pub first_child: u32,
    /// The element this one was split from, or [`NO_CHILD`] for a root (whose parent is the
    /// leaf cluster [`Tree::root_parent`]). Parents come before their children.
    pub parent: u32,
}

/// A node of the cluster BVH: an axis-aligned box of root patches.
#[derive(Clone, Debug)]
pub struct Cluster {
    /// Children: `Tree::cluster_children[first..first + count]`.
    pub first: u32,
    /// Number of children (2 for an inner cluster, ≤ [`LEAF_SIZE`] root elements for a leaf).
    pub count: u32,
    /// Centre of the box, scene units.
    pub centre: DVec3,
    /// Half the box diagonal: every point of the cluster is within this of `centre`.
    pub radius: f64,
    /// Total area of the root patches below, scene units squared.
    pub area: f64,
    /// Largest reflectance of any channel of any patch below (for the refinement oracle).
    pub max_reflectance: f64,
    /// Cosine of the widest angle between a root patch's normal and the area-weighted mean
    /// normal of all below (1 for coplanar patches facing one way; −1 when the normals cancel).
    pub cone_cos: f64,
    /// The part of `area` that is not buried ([`Tree::set_seen`]; all of it until then),
    /// scene units squared.
    pub seen_area: f64,
    /// Σ A·max(0, n_a) over the seen part A of the root patches below for the axes
    /// a = x, y, z, then Σ A·max(0, −n_a): how much of the cluster's seen area faces each of
    /// the six axis directions, scene units squared ([`super::ClusterGather`] weighs light by
    /// it; [`Tree::set_seen`]; over the whole area until then).
    pub seen_facing: [f64; 6],
}

/// Both hierarchies. Invariants: clusters are stored parents before children (cluster 0 is
/// the root when there is any); root element `i` is root patch `i` (elements `0..roots`);
/// `midpoints` holds the vertex made at the midpoint of every edge split so far, so
/// neighbours that share an edge share its midpoint (conforming output, [`super::output`]).
pub struct Tree {
    /// Vertices of all elements, scene units.
    pub positions: Vec<DVec3>,
    /// Edge (smaller vertex index, larger) → its midpoint vertex.
    pub midpoints: std::collections::HashMap<(u32, u32), u32>,
    /// All elements; the first `roots` are the root patches.
    pub elements: Vec<Element>,
    /// Number of root elements.
    pub roots: usize,
    /// Cluster BVH nodes, parents first.
    pub clusters: Vec<Cluster>,
    /// Children of the clusters (clusters or root elements).
    pub cluster_children: Vec<Node>,
    /// The leaf cluster holding each root element.
    pub root_parent: Vec<u32>,
}

impl Tree {
    /// The element trees' roots are `patches` (one element each, unsplit) and the cluster BVH
    /// is built over them. A scene of one patch has no cluster.
    pub fn new(patches: &Patches) -> Tree {
        let n = patches.len();
        let elements = (0..n)
            .map(|i| {
                let [a, b, c] = patches.corners(i);
                Element {
                    vertices: patches.triangles[i],
                    corner_normals: patches.corner_normal[i],
                    normal: patches.normal[i],
                    centroid: patches.centroid[i],
                    radius: circumradius([a, b, c], patches.centroid[i]),
                    area: patches.area[i],
                    root: i as u32,
                    first_child: NO_CHILD,
                    parent: NO_CHILD,
                }
            })
            .collect();
        let mut tree = Tree {
            positions: patches.positions.clone(),
            midpoints: Default::default(),
            elements,
            roots: n,
            clusters: Vec::new(),
            cluster_children: Vec::new(),
            root_parent: vec![u32::MAX; n],
        };
        if n > 1 {
            let mut order: Vec<u32> = (0..n as u32).collect();
            tree.build_clusters(patches, &mut order);
        }
        tree
    }

    /// The root node: the root cluster, or the only element.
    pub fn root(&self) -> Option<Node> {
        if !self.clusters.is_empty() {
            Some(Node::cluster(0))
        } else if self.roots == 1 {
            Some(Node::element(0))
        } else {
            None
        }
    }

    /// Builds the BVH over the root elements in `order` (top-down, median split on the longest
    /// axis of the centroids' box; deterministic). Iterative, parents before children.
    fn build_clusters(&mut self, patches: &Patches, order: &mut [u32]) {
        // (range of `order`, index of the cluster to fill)
        self.clusters.push(self.empty_cluster());
        let mut stack = vec![(0usize, order.len(), 0usize)];
        while let Some((lo, hi, c)) = stack.pop() {
            let items = &mut order[lo..hi];
            let (bmin, bmax) =
                crate::geometry::bounds(items.iter().flat_map(|&i| patches.corners(i as usize)));
            let area: f64 = items.iter().map(|&i| patches.area[i as usize]).sum();
            let max_reflectance = items
                .iter()
                .flat_map(|&i| patches.reflectance[i as usize])
                .fold(0.0, f64::max);
            let mut facing = [0.0; 6];
            for &i in items.iter() {
                let (a, n) = (patches.area[i as usize], patches.normal[i as usize]);
                for (f, w) in facing.iter_mut().zip(axis_weights(n)) {
                    *f += a * w;
                }
            }
            let mean: DVec3 = items
                .iter()
                .map(|&i| patches.area[i as usize] * patches.normal[i as usize])
                .sum();
            let cone_cos = match mean.try_normalize() {
                Some(m) => items
                    .iter()
                    .map(|&i| patches.normal[i as usize].dot(m))
                    .fold(1.0, f64::min),
                None => -1.0,
            };
            let first = self.cluster_children.len() as u32;
            let count;
            if items.len() <= LEAF_SIZE {
                count = items.len() as u32;
                for &i in items.iter() {
                    self.cluster_children.push(Node::element(i as usize));
                    self.root_parent[i as usize] = c as u32;
                }
            } else {
                let (cmin, cmax) =
                    crate::geometry::bounds(items.iter().map(|&i| patches.centroid[i as usize]));
                let axis = (cmax - cmin).max_position();
                let mid = items.len() / 2;
                items.select_nth_unstable_by(mid, |&a, &b| {
                    let (ka, kb) = (
                        patches.centroid[a as usize][axis],
                        patches.centroid[b as usize][axis],
                    );
                    ka.total_cmp(&kb).then(a.cmp(&b))
                });
                count = 2;
                for (l, h) in [(lo, lo + mid), (lo + mid, hi)] {
                    let child = self.clusters.len();
                    self.clusters.push(self.empty_cluster());
                    self.cluster_children.push(Node::cluster(child));
                    stack.push((l, h, child));
                }
            }
            self.clusters[c] = Cluster {
                first,
                count,
                centre: 0.5 * (bmin + bmax),
                radius: 0.5 * (bmax - bmin).length(),
                area,
                max_reflectance,
                cone_cos,
                seen_area: area,
                seen_facing: facing,
            };
        }
    }

    /// Sums the clusters' seen areas and facings from `visible[i]`, the visible fraction of
    /// root `i` (children after parents in storage, so bottom-up).
    pub fn set_seen(&mut self, visible: &[f64]) {
        for c in (0..self.clusters.len()).rev() {
            let (mut area, mut facing) = (0.0, [0.0; 6]);
            for &k in self.kids(c) {
                let (a, f) = match k.as_element() {
                    Some(e) => {
                        let a = self.elements[e].area * visible[e];
                        (a, axis_weights(self.elements[e].normal).map(|w| a * w))
                    }
                    None => {
                        let j = &self.clusters[k.as_cluster().unwrap()];
                        (j.seen_area, j.seen_facing)
                    }
                };
                area += a;
                for (s, x) in facing.iter_mut().zip(f) {
                    *s += x;
                }
            }
            self.clusters[c].seen_area = area;
            self.clusters[c].seen_facing = facing;
        }
    }

    fn empty_cluster(&self) -> Cluster {
        Cluster {
            first: 0,
            count: 0,
            centre: DVec3::ZERO,
            radius: 0.0,
            area: 0.0,
            max_reflectance: 0.0,
            cone_cos: -1.0,
            seen_area: 0.0,
            seen_facing: [0.0; 6],
        }
    }

    /// The children of a node: a cluster's children, an inner element's four, or none.
    pub fn children(&self, node: Node) -> Vec<Node> {
        match (node.as_element(), node.as_cluster()) {
            (Some(e), _) => {
                let f = self.elements[e].first_child;
                if f == NO_CHILD {
                    Vec::new()
                } else {
                    (f..f + 4).map(|k| Node::element(k as usize)).collect()
                }
            }
            (_, Some(c)) => self.kids(c).to_vec(),
            _ => unreachable!("a node is an element or a cluster"),
        }
    }

    /// Cluster `c`'s children.
    pub fn kids(&self, c: usize) -> &[Node] {
        let cl = &self.clusters[c];
        &self.cluster_children[cl.first as usize..(cl.first + cl.count) as usize]
    }

    /// Cluster `c` two levels down, at most [`MAX_PARTS`] nodes: each child element, and
    /// each child cluster's children, in order. What a cluster source's link weighs
    /// ([`super::Link::children`]).
    pub fn parts(&self, c: usize) -> impl Iterator<Item = Node> + '_ {
        self.kids(c)
            .iter()
            .flat_map(move |k| match k.as_cluster() {
                Some(j) => self.kids(j),
                None => std::slice::from_ref(k),
            })
            .copied()
    }

    /// How many of a cluster's [`Tree::parts`] child `k` gives.
    fn parts_in(&self, k: Node) -> usize {
        k.as_cluster()
            .map_or(1, |j| self.clusters[j].count as usize)
    }

    /// Area of a node, scene units squared.
    pub fn area(&self, node: Node) -> f64 {
        match node.as_element() {
            Some(e) => self.elements[e].area,
            None => self.clusters[node.as_cluster().unwrap()].area,
        }
    }

    /// Centre and bounding radius of a node, scene units.
    pub fn sphere(&self, node: Node) -> (DVec3, f64) {
        match node.as_element() {
            Some(e) => (self.elements[e].centroid, self.elements[e].radius),
            None => {
                let c = &self.clusters[node.as_cluster().unwrap()];
                (c.centre, c.radius)
            }
        }
    }

    /// The three corners of element `e`, scene units.
    pub fn corners(&self, e: usize) -> [DVec3; 3] {
        self.elements[e]
            .vertices
            .map(|v| self.positions[v as usize])
    }

    /// Unit smooth-surface normal of element `e` at barycentric point `b`.
    pub fn surface_normal(&self, e: usize, b: [f64; 3]) -> DVec3 {
        let el = &self.elements[e];
        let m = el.corner_normals;
        (b[0] * m[0] + b[1] * m[1] + b[2] * m[2])
            .try_normalize()
            .unwrap_or(el.normal)
    }

    /// Splits leaf element `e` into four at its edge midpoints (sharing a midpoint with any
    /// neighbour that split the same edge). Children keep the winding and the root.
    pub fn split(&mut self, e: usize) {
        debug_assert_eq!(self.elements[e].first_child, NO_CHILD);
        let el = self.elements[e].clone();
        let [a, b, c] = el.vertices;
        let [na, nb, nc] = el.corner_normals;
        let ab = self.midpoint(a, b);
        let bc = self.midpoint(b, c);
        let ca = self.midpoint(c, a);
        let (mab, mbc, mca) = (0.5 * (na + nb), 0.5 * (nb + nc), 0.5 * (nc + na));
        let first = self.elements.len() as u32;
        let kids = [
            ([a, ab, ca], [na, mab, mca]),
            ([ab, b, bc], [mab, nb, mbc]),
            ([ca, bc, c], [mca, mbc, nc]),
            ([bc, ca, ab], [mbc, mca, mab]),
        ];
        for (vertices, corner_normals) in kids {
            let p = vertices.map(|v| self.positions[v as usize]);
            let centroid = (p[0] + p[1] + p[2]) / 3.0;
            self.elements.push(Element {
                vertices,
                corner_normals,
                normal: el.normal,
                centroid,
                radius: circumradius(p, centroid),
                area: 0.25 * el.area,
                root: el.root,
                first_child: NO_CHILD,
                parent: e as u32,
            });
        }
        self.elements[e].first_child = first;
    }

    fn midpoint(&mut self, a: u32, b: u32) -> u32 {
        let key = (a.min(b), a.max(b));
        if let Some(&m) = self.midpoints.get(&key) {
            return m;
        }
        let m = self.positions.len() as u32;
        self.positions
            .push(0.5 * (self.positions[a as usize] + self.positions[b as usize]));
        self.midpoints.insert(key, m);
        m
    }

    /// `n` stratified random points on node `node`, each with the element it lies on and
    /// which of `node`'s parts it lies in ([`Sample::part`]): on an element, stratified over
    /// its area; in a cluster, each point on a root patch chosen with probability ∝ area
    /// (descending the BVH), then uniform on it.
    pub fn sample(&self, node: Node, n: usize, rng: &mut Rng, out: &mut Vec<Sample>) {
        out.clear();
        if let Some(e) = node.as_element() {
            let mut bs = Vec::with_capacity(n);
            stratified_triangle_barycentrics(n, rng, &mut bs);
            out.extend(bs.into_iter().map(|b| Sample {
                element: e,
                at: b,
                part: quarter_of(b),
            }));
            return;
        }
        let mut b = Vec::with_capacity(1);
        for _ in 0..n {
            let mut at = node;
            let (mut part, mut depth) = (0, 0);
            while let Some(c) = at.as_cluster() {
                let kids = self.kids(c);
                let mut u = rng.next_f64() * self.clusters[c].area;
                let mut pick = kids.len() - 1;
                for (i, &k) in kids.iter().enumerate() {
                    let a = self.area(k);
                    if u < a {
                        pick = i;
                        break;
                    }
                    u -= a;
                }
                // The parts before this one: a child element is one, a child cluster one
                // for each of its children.
                match depth {
                    0 => part = kids[..pick].iter().map(|&k| self.parts_in(k)).sum(),
                    1 => part += pick,
                    _ => {}
                }
                depth += 1;
                at = kids[pick];
            }
            b.clear();
            stratified_triangle_barycentrics(1, rng, &mut b);
            out.push(Sample {
                element: at.as_element().unwrap(),
                at: b[0],
                part: part as u8,
            });
        }
    }

    /// `n` random points on the part of cluster `c` that is not buried, with the element each
    /// lies on: a root patch chosen with probability ∝ its seen area (descending the BVH),
    /// then a point uniform on it when nothing of it is buried, else one of its unburied rule
    /// points chosen ∝ weight. Nothing when the whole cluster is buried. `burial` gives the
    /// roots' buried points and visible fractions, the same [`Tree::set_seen`] was given.
    pub fn sample_seen(
        &self,
        c: usize,
        n: usize,
        burial: super::rule::Burial,
        rng: &mut Rng,
        out: &mut Vec<(usize, [f64; 3])>,
    ) {
        out.clear();
        if self.clusters[c].seen_area <= 0.0 {
            return;
        }
        let seen_area = |k: Node| match k.as_element() {
            Some(e) => self.elements[e].area * burial.visible(e),
            None => self.clusters[k.as_cluster().unwrap()].seen_area,
        };
        let rule = super::rule::receiver_rule();
        let mut b = Vec::with_capacity(1);
        for _ in 0..n {
            let mut at = Node::cluster(c);
            while let Some(c) = at.as_cluster() {
                let kids = self.kids(c);
                let mut u = rng.next_f64() * self.clusters[c].seen_area;
                at = *kids.iter().rev().find(|&&k| seen_area(k) > 0.0).unwrap();
                for &k in kids {
                    let a = seen_area(k);
                    if u < a {
                        at = k;
                        break;
                    }
                    u -= a;
                }
            }
            let e = at.as_element().unwrap();
            let buried = burial.mask(e);
            if buried == 0 {
                b.clear();
                stratified_triangle_barycentrics(1, rng, &mut b);
                out.push((e, b[0]));
            } else {
                let weights = super::rule::unburied_weights(buried);
                let k = super::rule::pick_proportional(&weights, 1, rng.next_f64())
                    .expect("a root with seen area has an unburied point")[0];
                out.push((e, rule[k].0));
            }
        }
    }

    /// The point with barycentrics `b` on element `e`, scene units.
    pub fn point(&self, e: usize, b: [f64; 3]) -> DVec3 {
        let [p, q, r] = self.corners(e);
        b[0] * p + b[1] * q + b[2] * r
    }

    /// Visits the leaves below element `e` (itself if a leaf), depth first, children in order.
    pub fn leaves(&self, e: usize, visit: &mut impl FnMut(usize)) {
        let f = self.elements[e].first_child;
        if f == NO_CHILD {
            visit(e);
        } else {
            for k in f..f + 4 {
                self.leaves(k as usize, visit);
            }
        }
    }
}

/// How much a unit normal `n` faces each of the six axis directions (+x, +y, +z, −x, −y, −z):
/// max(0, n_a), then max(0, −n_a). [`Cluster::seen_facing`] sums these by area, and
/// [`super::ClusterGather`] shares light by them.
pub fn axis_weights(n: DVec3) -> [f64; 6] {
    [
        n.x.max(0.0),
        n.y.max(0.0),
        n.z.max(0.0),
        (-n.x).max(0.0),
        (-n.y).max(0.0),
        (-n.z).max(0.0),
    ]
}

fn circumradius(p: [DVec3; 3], centroid: DVec3) -> f64 {
    p.iter().map(|v| v.distance(centroid)).fold(0.0, f64::max)
}
