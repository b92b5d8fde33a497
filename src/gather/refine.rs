//! Adaptive refinement of the displayed mesh: output triangles are split where the gathered
//! radiance is not linear along their edges, so that what the viewer sees (vertex colours
//! interpolated across each triangle) follows shadow edges, penumbrae and the fall-off next to
//! a contact, which the patch mesh does not.
//!
//! The test of an edge (a, b) is the radiance at its midpoint m against what the triangle shows
//! there, (L_a + L_b)/2 (linear interpolation, Lischinski, Tampieri & Greenberg 1993 §5 refine
//! the display mesh the same way). The sharp part is the direct light, so the test evaluates it
//! exactly at m (the form factor of the emitters' visible pieces,
//! [`crate::geometry::visible`], cheap next to the hemisphere rays):
//!
//! split (a, b) when |Y(ρD_m) − Y(ρD_a + ρD_b)/2| > τ · max(Y((L_a + L_b)/2), Y_floor),
//!
//! Y the luminance, τ the tolerance, Y_floor a tenth of the mean luminance of the non-emitting
//! vertices ([`super::local_fit::dark_floor`]: darker points are not worth vertices). The
//! indirect light is smooth except near a contact or a narrow gap, where it falls off within
//! the gap's width; an edge whose endpoints' reflected indirect light differs by more than
//! 2τ · max(…) is split (its midpoint would show the mean of two values that differ that much),
//! and so is one whose midpoint's indirect light, estimated by [`TEST_RAYS`] hemisphere rays
//! (`full` only), departs from its ends' mean by more than τ · max(…) plus [`SIGNIFICANCE`]
//! standard errors of that estimate: a dark middle between lit ends, which neither the ends nor
//! the direct light show (a table's underside above a leg's top 5 mm below it, the floor under
//! a seat). An edge that test keeps whole is tested once more by the same departure taken ray
//! by ray (`Gatherer::coarse_indirect`: the same 16 directions from the midpoint and both
//! ends, so that much of what the three points share cancels): a bright middle between ends
//! darkened by what is beside them, which the midpoint's own rays' noise hides (a seat's
//! underside between corners that see the legs' tops 5 mm away). A midpoint whose test rays meet mostly the backs of surfaces is walled in where
//! nobody sees it ([`ENCLOSED`]: the floor under a partition of two wall faces), and its edge
//! is left alone.
//!
//! A split edge gets a new output vertex at its midpoint with its own final gather (after the
//! `cache` gather: the direct light its test found there, the point's costly part, and its own
//! indirect light), and the triangles around it are split conformingly (one, two or three split
//! edges give two, three or four triangles; a split edge is split in every triangle that has
//! it, on both sides of a crease), so no T-junction appears. New triangles' edges are tested
//! again, up to [`MAX_LEVELS`] times and down to [`MIN_EDGE`] of the scene's extent.
//!
//! The work is bounded: at most `budget` new vertices in all (the edges with the largest
//! deviation × √length first, at most half the remaining budget per level, the rest waiting for
//! the next),
//! and at most [`tests_per_new_vertex`] × the budget midpoint tests in all (the edges whose
//! endpoints differ most, a penumbra at an end counting as [`PENUMBRA_CONTRAST`], or whose
//! midpoint departs most from its ends' mean in a cheap estimate of the direct light, first,
//! again × √length), each of at most
//! [`MIDPOINT_SHADOW_RAYS`] shadow rays per emitter and [`TEST_RAYS`] hemisphere rays. Every
//! choice is ordered by the edges' vertex indices, so a fixed seed gives the same mesh for any
//! thread count.
//!
//! The cheap estimate (`Gatherer::coarse_direct`) is each exact emitter's unoccluded form
//! factor times the share of four fixed points of it that a shadow ray reaches. The points
//! are the same from every receiver, so the estimates at an edge's ends and midpoint are
//! correlated: where all three see every point it departs from linear only as the unoccluded
//! light does, and a shadow that falls between two lit ends (a chair leg's, 5 cm wide between
//! vertices 17 cm apart) darkens the midpoint's alone. Under many lights nearly every edge
//! of a floor has an end in some penumbra, and the ends' contrast does not see such a shadow
//! at all; on the generated office (seeds 1–3) the order by both displays 3.09, 3.20, 3.23 %
//! RMS against 3.24, 3.31, 3.59 % by the ends alone, for about 3 s of its bake (every candidate
//! edge's midpoint, four shadow rays per exact emitter triangle).
//!
//! Before the fit, the diagonal of two coplanar triangles is turned where the other one
//! interpolates the direct light better ([`super::flip`]): a shadow along a diagonal shows.
//!
//! The midpoints tested and left whole are not thrown away: the vertex values are fitted to
//! them at the end ([`super::local_fit`]), so where the budget ran out the display shows the
//! light around a vertex, not only at it (the midpoints of edges a flip took away are
//! dropped).
//!
//! Why deviation × √length: what a split buys is the squared error it removes over the area
//! the viewer sees. The error an edge leaves is mostly a discontinuity of the light crossing
//! its faces (a shadow edge, a penumbra, the rim of a contact), wrong over a strip as long as
//! the faces (∝ the edge's length L) and as wide as the transition: δ² · L, whose root orders
//! the edges. (By deviation alone, edges of millimetres at the sharpest features take the
//! budget from long edges across shadows, and the generated hall's long narrow shadows go
//! unresolved; by δ · L, as for a smooth error over the faces' whole area, the long edges
//! take it from the sharp features the Cornell box and the living room need. The point-wise
//! benchmark tells the three apart; the midpoint tests are ordered the same way, for the
//! same reason.)

use std::collections::{HashMap, HashSet};

use super::coarse::{coarse_direct_at, complete_coarse, edge, face_edges, Coarse, Edge};
use super::indirect::COARSE_RAYS;
use super::local_fit::{self, Midpoint};
use super::sites::StarFace;
use super::{Cache, Gather, Gathered, Gatherer};
use crate::bake::{BakedMesh, Site, SitePatches};
use crate::color::{luminance, Rgb};
use crate::distributed::{Reader, Writer};
use crate::light::emitter::{CACHE_MAX_SHADOW_RAYS, GATHER_MAX_SHADOW_RAYS, MIDPOINT_SHADOW_RAYS};
use crate::sampling::Rng;

/// τ by default: an edge is split where the light at its midpoint departs from what the
/// triangle shows there by more than 2 % of the local luminance.
pub const DEFAULT_TOLERANCE: f64 = 0.02;

/// New vertices, at most, when each gets `rays` hemisphere rays and a direct light that costs
/// `direct` more ([`super::Gatherer::direct_cost_per_point`], in hemisphere rays), after the
/// `full` or `direct` gather: as many as twice that gather's own budget of rays pays for
/// ([`super::AUTO_RAY_BUDGET`]), so that the refinement adds at most about twice as many rays
/// again, whatever the scene's size and its number of lights ([`budget_of`]). `direct` is what
/// the direct light costs (the exact emitters' visible pieces, [`super::EXACT_EMITTER_COST`]
/// each, rather than shadow rays per emitter): counted too high, it would stop a many-light
/// scene's refinement far short. The Cornell box uses the whole budget, and its displayed
/// error still falls from half this budget to all of it (the point-wise benchmark): the bound
/// is one of cost, not of accuracy.
pub fn budget(rays: usize, direct: usize) -> usize {
    budget_of(super::AUTO_RAY_BUDGET, rays, direct)
}

/// New vertices, at most, after a gather whose own budget is `gather_rays` hemisphere rays:
/// as many as twice that pays for at `rays` hemisphere rays and `direct` (in hemisphere rays)
/// each ([`budget`]).
pub fn budget_of(gather_rays: usize, rays: usize, direct: usize) -> usize {
    2 * gather_rays / (rays + direct).max(1)
}

/// New vertices, at most, of the display refinement after a `mode` gather of `vertices`
/// output vertices: [`budget`]; for the `cache` gather, twice what its own records' rays
/// ([`super::cache::RAY_BUDGET`], twice the `full` gather's) pay for, the same rule, and at
/// most [`CACHE_REFINE_SHARE`] × `vertices` as well. The bake and its estimate both ask here.
///
/// The `cache` gather's cost is not its hemisphere rays but the direct light it computes
/// exactly at every vertex (an emitter's visible pieces against its occluders, many on a
/// furnished scene), and the refinement computes the same at each new vertex and at each of its
/// [`CACHE_TESTS_PER_NEW_VERTEX`] midpoint tests. Bounding the new vertices by a share of the
/// output bounds the refinement's direct-light evaluations by the gather's own, on any scene,
/// whatever one costs: the rays' bound alone, which prices the direct light by a fixed
/// [`super::EXACT_EMITTER_COST`], let the refinement of a furnished office of 10⁵ triangles
/// cost 4.6× the gather at its vertices. The share binds on the offices; the rays' bound
/// binds where a point's direct light costs more (the generated hall of 10⁵ triangles, 784
/// emitting triangles), and there, bounded by the `full` gather's rays instead of the
/// records', its display showed 8.71 % RMS against 6.85 % with twice the vertices, for 1.27×
/// the bake, where a path tracer's error falls only to 0.89× (BENCHMARKS.md "Large outputs").
pub fn budget_for(mode: Gather, rays: usize, direct: usize, vertices: usize) -> usize {
    match mode {
        Gather::Cache => budget_of(super::cache::RAY_BUDGET, rays, direct)
            .min((CACHE_REFINE_SHARE * vertices as f64) as usize),
        _ => budget(rays, direct),
    }
}

/// `budget` new vertices times `factor` ([`crate::pipeline::Settings::display_budget`]),
/// rounded down; the midpoint tests follow, [`tests_per_new_vertex`] for each.
pub fn scaled(budget: usize, factor: f64) -> usize {
    (budget as f64 * factor) as usize
}

/// New vertices of the `cache` gather's display refinement per output vertex, at most
/// ([`budget_for`]): 1 / [`CACHE_TESTS_PER_NEW_VERTEX`], so that the tests evaluate the
/// direct light as many times as the gather did at the output's vertices. A new vertex takes
/// the direct light its edge's test found at the same point, so the vertices add only their
/// indirect light (the records', or a hemisphere where no record serves them). On the
/// generated hall, whose many small lights cast shadows the output does not follow, it leaves
/// most of them unresolved (BENCHMARKS.md "Large outputs: the `cache` gather").
pub const CACHE_REFINE_SHARE: f64 = 1.0 / CACHE_TESTS_PER_NEW_VERTEX as f64;

/// What an edge with an end in a penumbra (some emitter partly hidden there) adds to its
/// contrast, the relative difference of its ends' luminance, in the order of the midpoint
/// tests. The flag says that an emitter is partly hidden at the end, not how much of the light
/// it carries: under many lights nearly every point of a furnished room has one. Counted as a
/// full contrast (1), the floor's penumbral edges took every test before the long edges
/// across a desk, a partition or a monitor whose ends differ by a fifth or a half; at a
/// quarter the office of 10⁵ triangles displays 3.66, 3.58, 3.99 % RMS (seeds 1–3) against
/// 4.35, 4.26, 4.46 %, and 3.93 % at 0 (seed 1); the Cornell box, whose every edge is
/// tested, is the same to the byte, the hall of 10⁴ 4.47 % against 4.45 % (BENCHMARKS.md
/// "Large outputs: the `cache` gather").
pub const PENUMBRA_CONTRAST: f64 = 0.25;

/// Rounds of testing new triangles' edges, at most: each halves the edges it splits.
pub const MAX_LEVELS: usize = 8;

/// No edge shorter than this fraction of the scene's extent (its bounding box diagonal) is
/// tested.
pub const MIN_EDGE: f64 = 1e-3;

/// Hemisphere rays of a midpoint test's indirect light (`full` only): enough to see a
/// midpoint darker or brighter than its ends by a multiple of τ, not to value it.
pub const TEST_RAYS: usize = 16;

/// A midpoint's indirect light departs from its ends' mean only beyond this many of its
/// standard errors (estimated from its [`TEST_RAYS`]' spread), so noise alone rarely splits.
pub const SIGNIFICANCE: f64 = 2.0;

/// A midpoint whose test rays ([`TEST_RAYS`], `full` only) meet the backs of surfaces more
/// often than this is taken for walled in where no viewer sees it, though its normal ray may
/// meet a front (the floor's strip under a partition built of two wall faces, as
/// architectural models often build one: it sees the partition's backs, and the ceiling's
/// strip and the end walls through the slot): its edge is neither split nor fitted to it. Its
/// light (no direct light, the ends' indirect light) is not the light beside it: fitted to
/// such midpoints, the contact line's vertices would show the floor beside the partition
/// far too dark (the test `a_partition_of_two_wall_faces_does_not_darken_the_floor_beside_it`).
/// A seen point of a scene whose surfaces face the viewer meets no back; one beside the back
/// of a one-sided plane, about half. In a slot much higher than it is wide, nearly all of the
/// strip's points meet backs with more than half of their rays, while a higher threshold
/// misses a share of them and leaves contact vertices dark.
pub const ENCLOSED: f64 = 0.5;

/// Midpoint tests, in all, per vertex the budget allows, after a `full` or `direct` gather.
/// There a new vertex costs its hemisphere (64 to 1,024 rays) and a test only its direct light
/// and [`TEST_RAYS`], so tests are cheap next to vertices and many of them choose the edges
/// to split well.
pub const TESTS_PER_NEW_VERTEX: usize = 4;

/// Midpoint tests, in all, per vertex the budget allows, after the `cache` gather. There the
/// direct light, computed exactly at a point, is most of what a test or a vertex costs, so
/// each test not spent buys about a vertex. With 4, most tests were spent on edges that could
/// not be split: on the generated office three in four of the first level's tests found their
/// edge over τ, three times the vertices the level could add. At the same refinement seconds,
/// 2 tests a vertex (when a vertex still computed its own direct light: a third of the
/// output's vertices added, not a fifth) display 4.8 % RMS against 5.2 %, and 1 no better than
/// 2 (BENCHMARKS.md "Large outputs: the `cache` gather").
pub const CACHE_TESTS_PER_NEW_VERTEX: usize = 2;

/// Midpoint tests, in all, per vertex the budget allows after a `mode` gather:
/// [`CACHE_TESTS_PER_NEW_VERTEX`] for `cache`, else [`TESTS_PER_NEW_VERTEX`].
pub fn tests_per_new_vertex(mode: Gather) -> usize {
    match mode {
        Gather::Cache => CACHE_TESTS_PER_NEW_VERTEX,
        _ => TESTS_PER_NEW_VERTEX,
    }
}

/// Rays of a midpoint test for the Le of the emitters its direct term leaves to the
/// hemisphere (`cache` only; a vertex casts [`super::cache::EMISSION_RAYS`]). The test asks
/// whether the midpoint departs from its ends' mean by τ, not its value: 64 stratified rays
/// leave that share a noise of about 5e-3 of the light (the furnace's per-vertex figure at
/// 64 rays, [`super::cache::EMISSION_RAYS`]), a quarter of the default τ.
pub const TEST_EMISSION_RAYS: usize = 64;

/// What the refinement did.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Refined {
    /// Output vertices added.
    pub vertices: usize,
    /// Edge midpoints tested.
    pub tests: usize,
    /// Levels that split at least one edge.
    pub levels: usize,
    /// Output vertices whose indirect light is its local fit's ([`super::local_fit`]).
    pub denoised: usize,
    /// Output vertices given the chord correction, by 0 where the light is linear
    /// ([`super::local_fit`]).
    pub chord: usize,
    /// Tested midpoints of edges left whole that the vertex values were fitted to
    /// ([`super::local_fit`]).
    pub midpoints: usize,
    /// Crossing points of two diagonals where the direct light was evaluated to choose one
    /// ([`super::flip`]).
    pub flip_tests: usize,
    /// Diagonals turned to follow the direct light ([`super::flip`]).
    pub flips: usize,
    /// Stopped at [`Plan::deadline`] (a bake's time budget) before its budget or its
    /// candidates ran out.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub out_of_time: bool,
}

/// The output mesh being refined, with what the gather found at each vertex.
struct Display<'m> {
    mesh: &'m mut BakedMesh,
    sites: Vec<Site>,
    values: Vec<Gathered>,
    /// The patch of each output face.
    face_patch: Vec<u32>,
}

/// What to refine with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    /// The gather the new vertices get (`direct` interpolates their indirect part; `none`
    /// refines nothing).
    pub mode: Gather,
    /// Hemisphere rays of a `full` gather per new vertex.
    pub rays: usize,
    /// τ, relative; 0 refines nothing.
    pub tolerance: f64,
    /// New vertices, at most ([`budget`]).
    pub budget: usize,
    /// No level of tests starts after this instant (a bake's time budget); `None`: no limit.
    pub deadline: Option<std::time::Instant>,
}

/// Refines `mesh` (whose vertices are `sites`, gathered as `values`; face i is patch i) in
/// place by `plan`: see the module documentation. Returns what was done.
pub fn refine(
    gatherer: &Gatherer,
    mesh: &mut BakedMesh,
    sites: Vec<Site>,
    values: Vec<Gathered>,
    plan: &Plan,
    cache: Option<&Cache>,
    visible_fraction: &[f64],
) -> Refined {
    let mut done = Refined::default();
    let Plan {
        mode,
        rays,
        tolerance,
        budget,
        deadline,
    } = *plan;
    let face_patch = (0..mesh.faces.len() as u32).collect();
    let mut d = Display {
        mesh,
        sites,
        values,
        face_patch,
    };
    if mode == Gather::None || tolerance <= 0.0 || budget == 0 {
        regather_rims(gatherer, &mut d, (mode, rays, cache), visible_fraction);
        d.mesh.vertex_radiance = d.values.iter().map(|g| g.radiance).collect();
        return done;
    }
    // The most the levels can add, reserved once: grown by doubling, the output's largest
    // arrays would hold up to twice their length at the flips (the bake's peak on a large
    // output). A split edge adds a vertex and one or two faces on each side. (A budget
    // raised past the output's own size grows them as it goes.)
    let more = budget.min(d.sites.len());
    d.sites.reserve_exact(more);
    d.values.reserve_exact(more);
    d.mesh.faces.reserve_exact(2 * more);
    d.face_patch.reserve_exact(2 * more);
    let emission = &gatherer.patches.emission;
    let floor = local_fit::dark_floor(&d.values, |v| {
        emission[d.sites[v].patches[0] as usize]
            .iter()
            .any(|&c| c > 0.0)
    });
    let min_edge2 = (MIN_EDGE * gatherer.extent()).powi(2);
    // Edges tested and kept whole, and edges over τ waiting for budget: not tested again.
    let mut kept: HashSet<Edge> = HashSet::new();
    let mut deferred: Vec<Split> = Vec::new();
    let tests_per_vertex = tests_per_new_vertex(mode);
    let mut tests_left = tests_per_vertex * budget;
    let mut candidates: Vec<usize> = (0..d.mesh.faces.len()).collect();
    let mut next_mesh_vertex = d.sites.iter().map(|s| s.mesh_vertex + 1).max().unwrap_or(0);
    // What the tests found at the midpoints, for the final fit of the values (those of the
    // edges split are dropped at the end: their midpoints became vertices).
    let mut midpoints: Vec<Midpoint> = Vec::new();
    // The direct light the `cache` gather's tests found at the midpoints of the edges to
    // split: their new vertices take it.
    let mut lit_at: HashMap<Edge, Lit> = HashMap::new();
    // Progress in points evaluated, out of the most the budget allows (tests and new
    // vertices); a refinement that stops early ends its stage there.
    let progress = crate::progress::stage("display refinement", Some((tests_left + budget) as u64));
    // Each vertex's cheap direct light (`coarse_direct_at`), once computed.
    let mut coarse_at = Coarse::default();

    for _ in 0..MAX_LEVELS {
        let remaining = budget - done.vertices;
        if remaining == 0 || (candidates.is_empty() && deferred.is_empty()) {
            break;
        }
        if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            done.out_of_time = true;
            break;
        }
        let waiting: HashSet<Edge> = deferred.iter().map(|d| d.edge).collect();
        // The candidate faces' edges, long enough and not tested before, with their contrast
        // (× √length) and the luminance their deviation is relative to.
        // (The fourth value: √length, which orders the splits too.)
        let mut edges: Vec<(f64, Edge, f64, f64)> = Vec::new();
        let mut seen = HashSet::new();
        for &f in &candidates {
            for e in face_edges(d.mesh.faces[f]) {
                if kept.contains(&e) || waiting.contains(&e) || !seen.insert(e) {
                    continue;
                }
                let (a, b) = (e.0 as usize, e.1 as usize);
                let (va, vb) = (&d.values[a], &d.values[b]);
                if va.buried || vb.buried {
                    continue;
                }
                if d.sites[a].position.distance_squared(d.sites[b].position) < min_edge2 {
                    continue;
                }
                let reference = luminance(mid(va.radiance, vb.radiance)).max(floor);
                let mut contrast =
                    (luminance(va.radiance) - luminance(vb.radiance)).abs() / reference;
                if va.penumbra || vb.penumbra {
                    contrast += PENUMBRA_CONTRAST;
                }
                let root = d.sites[a].position.distance(d.sites[b].position).sqrt();
                edges.push((contrast * root, e, reference, root));
            }
        }
        drop(seen);
        // An edge whose ends are alike may hide a shadow between them: the cheap, correlated
        // estimate of the direct light at its midpoint shows it (see the module doc).
        let departures = coarse_departures(gatherer, &d, &edges, &mut coarse_at, visible_fraction);
        for (e, departure) in edges.iter_mut().zip(departures) {
            e.0 = e.0.max(departure * e.3);
        }
        // The most promising edges first, as many as the budget pays tests for.
        edges.sort_unstable_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let allowed = remaining.div_ceil(2);
        edges.truncate(tests_left.min(tests_per_vertex * allowed));
        // The first level's candidates are every edge of the output: not kept through it.
        edges.shrink_to_fit();
        tests_left -= edges.len();
        done.tests += edges.len();
        let seed = gatherer.seed();
        // Each test's deviation, and the radiance it found at the midpoint (its direct
        // light, the ends' mean indirect light; None where the midpoint is buried or its
        // exact emitters are not its ends').
        let test = |i: usize| {
            let (_, e, reference, _) = edges[i];
            progress.advance(1);
            let mut found = None;
            let mut lit = None;
            let (va, vb) = (&d.values[e.0 as usize], &d.values[e.1 as usize]);
            // The indirect light: endpoints that differ this much (a contact's fall-off).
            let indirect =
                0.5 * (luminance(va.indirect) - luminance(vb.indirect)).abs() / reference;
            let site = d.midpoint_site(e, &[]);
            let at_midpoint = gatherer.spot(&site, visible_fraction).map_or(0.0, |spot| {
                let mut rng = Rng::new(&[seed, e.0 as u64, e.1 as u64, 0x7E57]);
                let (dm, penumbra, exact) =
                    gatherer.reflected_direct(&spot, MIDPOINT_SHADOW_RAYS, &mut rng);
                // Kept where the ends and the midpoint compute the same emitters exactly
                // (else the ends' indirect light counts another set of emitters' light).
                let key = gatherer.exact_key(&exact);
                if va.exact_key == key && vb.exact_key == key {
                    let le = gatherer.patches.emission[spot.patch as usize];
                    let ends = mid(va.indirect, vb.indirect);
                    found = Some(std::array::from_fn(|c| le[c] + dm[c] + ends[c]));
                }
                let direct =
                    (luminance(dm) - luminance(mid(va.direct, vb.direct))).abs() / reference;
                if !matches!(mode, Gather::Full | Gather::Cache) {
                    return direct;
                }
                if mode == Gather::Cache {
                    lit = Some(Lit {
                        x: spot.x,
                        n: spot.n,
                        patch: spot.patch,
                        direct: dm,
                        penumbra,
                        exact: exact.clone(),
                    });
                }
                // The indirect light at the midpoint, by a few rays (or the `cache`
                // gather's records where they serve it): its departure from the ends'
                // mean beyond SIGNIFICANCE standard errors (a dark middle between bright
                // ends: above a table leg's top, 5 mm under the table).
                let (im, error, backs) = match cache.and_then(|c| c.at(spot.x, spot.n)) {
                    Some(reflected) => {
                        // Its direct light is `dm` above: only the indirect part is read.
                        let im = gatherer.cached_reflected(
                            &spot,
                            reflected,
                            &exact,
                            TEST_EMISSION_RAYS,
                            &mut rng,
                        );
                        (im, 0.0, gatherer.backs(&spot, TEST_RAYS, &mut rng))
                    }
                    None => gatherer.reflected_indirect(&spot, &exact, TEST_RAYS, &mut rng),
                };
                if backs > ENCLOSED {
                    // Walled in by the backs of surfaces: nobody sees it (see ENCLOSED).
                    found = None;
                    lit = None;
                    return 0.0;
                }
                let departure = (luminance(im) - luminance(mid(va.indirect, vb.indirect))).abs()
                    - SIGNIFICANCE * error;
                let deviation = direct.max(departure.max(0.0) / reference);
                if deviation > tolerance {
                    return deviation;
                }
                // Kept whole so far: the same departure ray by ray, the ends' rays along the
                // midpoint's, shows a few per cent that the rays' own noise hides.
                let [Some(a), Some(b)] =
                    [e.0, e.1].map(|v| gatherer.spot(&d.sites[v as usize], visible_fraction))
                else {
                    return deviation;
                };
                let correlated = correlated_departure(gatherer, [&spot, &a, &b]);
                deviation.max(correlated / reference)
            });
            (at_midpoint.max(indirect), found, lit)
        };
        // Shared among the ranks of a bake over several processes, as the gather is.
        let write = |(x, found, lit): &(f64, Option<Rgb>, Option<Lit>), w: &mut Writer| {
            w.f64(*x);
            w.bytes(&[found.is_some() as u8]);
            found.unwrap_or_default().iter().for_each(|&v| w.f64(v));
            Lit::write(lit.as_ref(), w);
        };
        let read = |r: &mut Reader| {
            let (x, [some]) = (r.f64(), r.bytes());
            let found = [r.f64(), r.f64(), r.f64()];
            (x, (some != 0).then_some(found), Lit::read(r))
        };
        let tests: Vec<(f64, Option<Rgb>, Option<Lit>)> =
            gatherer.comm.map_shared(edges.len(), test, write, read);
        let mut split: Vec<Split> = std::mem::take(&mut deferred);
        for (&(_, edge, _, root), (deviation, found, lit)) in edges.iter().zip(tests) {
            if let Some(radiance) = found {
                midpoints.push(Midpoint {
                    ends: [edge.0, edge.1],
                    radiance,
                });
            }
            if deviation > tolerance {
                split.push(Split {
                    priority: deviation * root,
                    edge,
                });
                if let Some(lit) = lit {
                    lit_at.insert(edge, lit);
                }
            } else {
                kept.insert(edge);
            }
        }
        split.sort_unstable_by(|x, y| y.priority.total_cmp(&x.priority).then(x.edge.cmp(&y.edge)));
        // The largest priorities first, at most half the remaining budget per level so that
        // the edges of the new triangles at the sharpest features can be split in turn; the
        // rest wait for the next level. Every output edge at the same place (both sides of a
        // crease) splits with the one chosen.
        let mut chosen: Vec<Edge> = Vec::new();
        // Chosen edges with other output edges at the same place: their midpoints are shared.
        let mut beside_others: HashSet<Edge> = HashSet::new();
        {
            let by_place = d.edges_at(split.iter().map(|s| d.place(s.edge)).collect());
            let mut placed = HashSet::new();
            for s in split {
                let place = d.place(s.edge);
                if placed.contains(&place) {
                    continue;
                }
                let sides = &by_place[&place];
                if chosen.len() + sides.len() > allowed {
                    deferred.push(s);
                    continue;
                }
                placed.insert(place);
                chosen.extend(sides.iter().copied());
                if sides.len() > 1 {
                    beside_others.extend(sides.iter().copied());
                }
            }
        }
        if chosen.is_empty() {
            break;
        }
        chosen.sort_unstable();
        chosen.dedup();
        // New vertices, one per chosen edge, in edge order; one mesh vertex per place.
        let mut place_vertex: HashMap<Edge, u32> = HashMap::new();
        let mut midpoint: HashMap<Edge, u32> = HashMap::new();
        let first = d.sites.len();
        let faces_of = d.faces_of(&chosen);
        for &e in &chosen {
            let mv = *place_vertex.entry(d.place(e)).or_insert_with(|| {
                next_mesh_vertex += 1;
                next_mesh_vertex - 1
            });
            let mut site = d.midpoint_site(e, &faces_of[&e]);
            site.mesh_vertex = mv;
            site.shared = beside_others.contains(&e);
            midpoint.insert(e, d.sites.len() as u32);
            d.sites.push(site);
        }
        let new_vertex = |i: usize| {
            let v = first + i;
            progress.advance(1);
            let site = &d.sites[v];
            let endpoints = chosen[v - first];
            let (va, vb) = (
                &d.values[endpoints.0 as usize],
                &d.values[endpoints.1 as usize],
            );
            match gatherer.spot(site, visible_fraction) {
                None => Gathered::buried(mid(va.radiance, vb.radiance)),
                Some(spot) => {
                    let mut rng = gatherer.vertex_rng(v);
                    // The direct light: the one its test found at the same point (`cache`),
                    // else its own.
                    let direct = lit_at
                        .get(&endpoints)
                        .filter(|l| l.x == spot.x && l.n == spot.n && l.patch == spot.patch)
                        .map(|l| (l.direct, l.penumbra, l.exact.clone()))
                        .unwrap_or_else(|| {
                            let most = match mode {
                                Gather::Cache => CACHE_MAX_SHADOW_RAYS,
                                _ => GATHER_MAX_SHADOW_RAYS,
                            };
                            gatherer.reflected_direct(&spot, most, &mut rng)
                        });
                    // `full`: the new vertex gathers its own indirect light too. The
                    // ends' mean would do across a shadow edge, where the indirect light
                    // is smooth, but not where it bends between them: beside a contact
                    // or a concave corner (a floor point millimetres from a sofa's side is
                    // far brighter than its ends' mean) or where the ends count different
                    // emitters' Le in it (many lights). The budget pays for it: it
                    // counts each new vertex at the gather's full rays.
                    let cached = cache.and_then(|c| c.at(spot.x, spot.n));
                    if let Some(reflected) = cached {
                        // `cache`: the records' light where they serve the new vertex.
                        gatherer.cached_vertex_lit(&spot, reflected, direct, &mut rng)
                    } else if matches!(mode, Gather::Full | Gather::Cache) {
                        gatherer.full_lit(&spot, rays, direct, &mut rng)
                    } else {
                        let (direct, penumbra, exact) = direct;
                        let indirect = mid(va.indirect, vb.indirect);
                        let direct = (direct, penumbra, exact.as_slice());
                        gatherer.with_emission(spot.patch as usize, direct, indirect)
                    }
                }
            }
        };
        let new_values = gatherer.comm.map_shared(
            d.sites.len() - first,
            new_vertex,
            Gathered::write,
            Gathered::read,
        );
        d.values.extend(new_values);
        done.vertices += chosen.len();
        done.levels += 1;
        candidates = d.split_faces(&midpoint);
    }
    // What only the levels needed goes before the flips and the fit, whose own arrays make
    // the bake's peak on a large output (BENCHMARKS.md "Large outputs: the `cache` gather").
    drop((kept, deferred, lit_at, candidates));
    // The diagonals turned where the other one follows the direct light (before the fit,
    // which fits the vertex values to the faces as they end).
    if deadline.is_none_or(|d| std::time::Instant::now() < d) {
        let shown: Vec<Rgb> = d.values.iter().map(|g| g.radiance).collect();
        let flipped = super::flip::flip_edges(
            gatherer,
            (&mut d.mesh.faces, &d.face_patch),
            (&d.sites, &d.values, &shown),
            (tolerance, floor),
            (&mut coarse_at, visible_fraction),
        );
        (done.flip_tests, done.flips) = (flipped.tests, flipped.flips);
    }
    drop(coarse_at);
    regather_rims(gatherer, &mut d, (mode, rays, cache), visible_fraction);
    d.mesh.positions = std::mem::take(&mut d.sites)
        .iter()
        .map(|s| [s.position.x, s.position.y, s.position.z])
        .collect();
    {
        let present: HashSet<Edge> = d.mesh.faces.iter().flat_map(|&f| face_edges(f)).collect();
        midpoints.retain(|m| present.contains(&edge(m.ends[0], m.ends[1])));
    }
    let corrected = local_fit::correct(d.mesh, &d.values, &midpoints, tolerance, floor);
    (done.denoised, done.chord, done.midpoints) =
        (corrected.denoised, corrected.chord, corrected.midpoints);
    done
}

/// Gathers again, as `mode` gathers a vertex, each vertex on a covering face's outline or
/// under it where surfaces meet ([`Gatherer::rim_gap`]), at the point where the rim's profile
/// is its mean over the faces the vertex ended with ([`super::sites::rim_inset`] of their
/// centroids' mean distance): the refinement has made those faces narrower than the patches
/// the first gather knew where it split beside the rim, and the steeper part of the profile
/// they then span is nearer the rim. Only the `full` and `cache` gathers (the others' light
/// is not a point's).
fn regather_rims(
    gatherer: &Gatherer,
    d: &mut Display,
    (mode, rays, cache): (Gather, usize, Option<&Cache>),
    visible_fraction: &[f64],
) {
    if !matches!(mode, Gather::Full | Gather::Cache) {
        return;
    }
    let rims: HashMap<u32, usize> = (0..d.sites.len())
        .filter(|&v| gatherer.rim_gap(&d.sites[v]) > 0.0)
        .enumerate()
        .map(|(i, v)| (v as u32, i))
        .collect();
    if rims.is_empty() {
        return;
    }
    // Each rim vertex's faces (their indices).
    let mut star_faces: Vec<Vec<u32>> = vec![Vec::new(); rims.len()];
    for (k, f) in d.mesh.faces.iter().enumerate() {
        for v in f {
            if let Some(&i) = rims.get(v) {
                star_faces[i].push(k as u32);
            }
        }
    }
    let mut order: Vec<(u32, usize)> = rims.into_iter().collect();
    order.sort_unstable();
    let regathered = gatherer.comm.map_shared(
        order.len(),
        |k| {
            let (v, i) = order[k];
            let site = &d.sites[v as usize];
            let faces: Vec<StarFace> = star_faces[i]
                .iter()
                .map(|&k| {
                    let f = d.mesh.faces[k as usize];
                    StarFace {
                        corners: f.map(|c| d.sites[c as usize].position),
                        vertex: f.iter().position(|&c| c == v).unwrap_or(0),
                        patch: d.face_patch[k as usize],
                    }
                })
                .collect();
            let reach = faces.iter().map(StarFace::reach).sum::<f64>() / faces.len().max(1) as f64;
            let spot = (!faces.is_empty())
                .then(|| gatherer.spot_within(site, visible_fraction, Some(reach)))
                .flatten();
            // Kept where the faces are as narrow as the rim (the point did not move).
            let first = gatherer.spot(site, visible_fraction);
            let (Some(spot), Some(first)) = (spot, first) else {
                return d.values[v as usize];
            };
            if spot.x == first.x {
                return d.values[v as usize];
            }
            let mut rng = gatherer.vertex_rng(v as usize);
            let reflected = cache.and_then(|c| c.at(spot.x, spot.n));
            let max_rays = if reflected.is_some() {
                CACHE_MAX_SHADOW_RAYS
            } else {
                GATHER_MAX_SHADOW_RAYS
            };
            let (direct, sharp) = gatherer.rim_direct(&spot, &faces, max_rays, &mut rng);
            let gathered = match reflected {
                Some(reflected) => gatherer.cached_vertex_lit(&spot, reflected, direct, &mut rng),
                None => gatherer.full_lit(&spot, rays, direct, &mut rng),
            };
            match sharp {
                Some(star) => star.shown(gathered),
                None => gathered,
            }
        },
        Gathered::write,
        Gathered::read,
    );
    for ((v, _), g) in order.into_iter().zip(regathered) {
        d.values[v as usize] = g;
    }
}

/// The departure of each edge's midpoint from its ends' mean in the cheap direct light
/// ([`Gatherer::coarse_direct`]), relative to the edge's reference luminance (`edges[i].2`);
/// 0 where an end or the midpoint is buried or they compute different emitters exactly (the
/// estimates would not be correlated). `coarse_at` keeps each vertex's estimate across levels.
fn coarse_departures(
    gatherer: &Gatherer,
    d: &Display,
    edges: &[(f64, Edge, f64, f64)],
    coarse_at: &mut Coarse,
    visible_fraction: &[f64],
) -> Vec<f64> {
    let ends = edges.iter().flat_map(|e| [e.1 .0, e.1 .1]);
    complete_coarse(gatherer, &d.sites, ends, coarse_at, visible_fraction);
    let coarse_at = &*coarse_at;
    gatherer.comm.map_shared(
        edges.len(),
        |i| {
            let (_, e, reference, _) = edges[i];
            let (Some((ka, da)), Some((kb, db))) = (coarse_at[&e.0], coarse_at[&e.1]) else {
                return 0.0;
            };
            match coarse_direct_at(gatherer, &d.midpoint_site(e, &[]), visible_fraction) {
                Some((km, dm)) if km == ka && km == kb => {
                    (luminance(dm) - luminance(mid(da, db))).abs() / reference
                }
                _ => 0.0,
            }
        },
        |x, w| w.f64(*x),
        |r| r.f64(),
    )
}

/// Normals whose cosine is at least this are the same for [`correlated_departure`]: their
/// frames, and so their rays' directions, agree.
const SAME_NORMAL: f64 = 1.0 - 1e-9;

/// How far the reflected indirect light at an edge's midpoint `m` departs from the mean of its
/// ends' (`a`, `b`), ray by ray in the cheap estimate
/// ([`Gatherer::coarse_indirect`]: the same directions from all three), less [`SIGNIFICANCE`]
/// standard errors of the rays' differences (an upper bound of it: the rays are stratified),
/// at least 0; luminance. 0 unless all three have the same normal. Where the three points see the same surfaces most of the rays' noise cancels in
/// the differences, and a departure of a few per cent shows with 16 rays that alone carry a
/// noise of 10–25 %: the middle of a seat's underside, lit by the floor, between two corners
/// that see the legs' dark tops 5 mm away.
fn correlated_departure(gatherer: &Gatherer, [m, a, b]: [&super::sites::Spot; 3]) -> f64 {
    if a.n.dot(m.n) < SAME_NORMAL || b.n.dot(m.n) < SAME_NORMAL {
        return 0.0;
    }
    let [m, a, b] = [m, a, b].map(|s| gatherer.coarse_indirect(s));
    let k = COARSE_RAYS as f64;
    let d: [f64; COARSE_RAYS] =
        std::array::from_fn(|r| f64::from(m[r]) - 0.5 * (f64::from(a[r]) + f64::from(b[r])));
    let mean = d.iter().sum::<f64>() / k;
    let spread = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0);
    (mean.abs() - SIGNIFICANCE * (spread / k).sqrt()).max(0.0)
}

/// An edge to split, and why.
#[derive(Debug, Clone, Copy)]
struct Split {
    /// Its test's deviation (relative) × √(its length) (see [`refine`]'s documentation).
    priority: f64,
    edge: Edge,
}

/// The reflected direct light a `cache` test computed at an edge's midpoint
/// ([`Gatherer::reflected_direct`] at `x`, `n` on `patch`): the vertex that splitting the edge
/// puts at the same point takes it instead of computing it again. Its emitters past the exact
/// visible pieces got at most [`MIDPOINT_SHADOW_RAYS`] shadow rays in a penumbra, as many as
/// a `cache` vertex's own ([`CACHE_MAX_SHADOW_RAYS`]).
#[derive(Debug, Clone)]
struct Lit {
    x: glam::DVec3,
    n: glam::DVec3,
    patch: u32,
    direct: Rgb,
    penumbra: bool,
    exact: Vec<u32>,
}

impl Lit {
    /// Writes `lit` (or its absence) for another rank ([`Lit::read`] reads it).
    fn write(lit: Option<&Lit>, w: &mut Writer) {
        w.bytes(&[lit.is_some() as u8]);
        if let Some(l) = lit {
            l.x.to_array()
                .iter()
                .chain(&l.n.to_array())
                .chain(&l.direct)
                .for_each(|&v| w.f64(v));
            w.u32(l.patch);
            w.bytes(&[l.penumbra as u8]);
            w.u32(l.exact.len() as u32);
            l.exact.iter().for_each(|&k| w.u32(k));
        }
    }

    fn read(r: &mut Reader) -> Option<Lit> {
        let [some] = r.bytes();
        if some == 0 {
            return None;
        }
        let mut v = || glam::DVec3::new(r.f64(), r.f64(), r.f64());
        let (x, n) = (v(), v());
        let direct = [r.f64(), r.f64(), r.f64()];
        let patch = r.u32();
        let [penumbra] = r.bytes();
        let exact = (0..r.u32()).map(|_| r.u32()).collect();
        Some(Lit {
            x,
            n,
            patch,
            direct,
            penumbra: penumbra != 0,
            exact,
        })
    }
}

fn mid(a: Rgb, b: Rgb) -> Rgb {
    std::array::from_fn(|c| 0.5 * (a[c] + b[c]))
}

impl Display<'_> {
    /// Where an output edge lies: its endpoints' mesh vertices (lower first).
    fn place(&self, e: Edge) -> Edge {
        edge(
            self.sites[e.0 as usize].mesh_vertex,
            self.sites[e.1 as usize].mesh_vertex,
        )
    }

    /// The output edges at each of `places`, grouped by place (only those: a map of every
    /// edge would be the largest thing a level holds on a large output).
    fn edges_at(&self, places: HashSet<Edge>) -> HashMap<Edge, Vec<Edge>> {
        let mut map: HashMap<Edge, Vec<Edge>> = HashMap::new();
        for &face in &self.mesh.faces {
            for e in face_edges(face) {
                let place = self.place(e);
                if !places.contains(&place) {
                    continue;
                }
                let sides = map.entry(place).or_default();
                if !sides.contains(&e) {
                    sides.push(e);
                }
            }
        }
        map
    }

    /// The patches of the faces that have each of `edges`.
    fn faces_of(&self, edges: &[Edge]) -> HashMap<Edge, Vec<u32>> {
        let wanted: HashSet<Edge> = edges.iter().copied().collect();
        let mut map: HashMap<Edge, Vec<u32>> = HashMap::new();
        for (f, &face) in self.mesh.faces.iter().enumerate() {
            for e in face_edges(face) {
                if wanted.contains(&e) {
                    let patches = map.entry(e).or_default();
                    let p = self.face_patch[f];
                    if !patches.contains(&p) {
                        patches.push(p);
                    }
                }
            }
        }
        map
    }

    /// The site at the midpoint of output edge `e`, on `patches` (its endpoints' patches when
    /// empty: enough to find the point's gather spot for a test).
    fn midpoint_site(&self, e: Edge, patches: &[u32]) -> Site {
        let (a, b) = (&self.sites[e.0 as usize], &self.sites[e.1 as usize]);
        let patches = if patches.is_empty() {
            let mut common: SitePatches = a
                .patches
                .iter()
                .copied()
                .filter(|p| b.patches.contains(p))
                .collect();
            if common.is_empty() {
                common = a.patches.clone();
            }
            common
        } else {
            SitePatches::from_slice(patches)
        };
        Site {
            position: 0.5 * (a.position + b.position),
            normal: (a.normal + b.normal).normalize_or(a.normal),
            patches,
            shared: a.shared && b.shared,
            mesh_vertex: u32::MAX,
            // Along a covering face's outline, the midpoint is on it too.
            gap: a.gap.min(b.gap),
        }
    }

    /// Splits every face with a split edge (`midpoint` of each), conformingly; returns the
    /// new faces (the first child keeps the parent's index, the others are appended).
    fn split_faces(&mut self, midpoint: &HashMap<Edge, u32>) -> Vec<usize> {
        let mut changed = Vec::new();
        for f in 0..self.mesh.faces.len() {
            let [a, b, c] = self.mesh.faces[f];
            let m = |x: u32, y: u32| midpoint.get(&edge(x, y)).copied();
            let (mab, mbc, mca) = (m(a, b), m(b, c), m(c, a));
            let children: Vec<[u32; 3]> = match (mab, mbc, mca) {
                (None, None, None) => continue,
                (Some(x), Some(y), Some(z)) => {
                    vec![[a, x, z], [x, b, y], [z, y, c], [x, y, z]]
                }
                (Some(x), None, None) => vec![[a, x, c], [x, b, c]],
                (None, Some(y), None) => vec![[b, y, a], [y, c, a]],
                (None, None, Some(z)) => vec![[c, z, b], [z, a, b]],
                (Some(x), Some(y), None) => self.two([a, b, c], x, y),
                (None, Some(y), Some(z)) => self.two([b, c, a], y, z),
                (Some(x), None, Some(z)) => self.two([c, a, b], z, x),
            };
            let patch = self.face_patch[f];
            let radiance = self.mesh.face_radiance[f];
            for (k, child) in children.into_iter().enumerate() {
                if k == 0 {
                    self.mesh.faces[f] = child;
                    changed.push(f);
                } else {
                    changed.push(self.mesh.faces.len());
                    self.mesh.faces.push(child);
                    self.face_patch.push(patch);
                    self.mesh.face_radiance.push(radiance);
                }
            }
        }
        changed
    }

    /// Triangle [a, b, c] with its edges ab (midpoint x) and bc (midpoint y) split: the
    /// corner triangle at b and the quad a x y c cut along its shorter diagonal.
    fn two(&self, [a, b, c]: [u32; 3], x: u32, y: u32) -> Vec<[u32; 3]> {
        let p = |v: u32| self.sites[v as usize].position;
        let corner = [x, b, y];
        if p(a).distance_squared(p(y)) <= p(x).distance_squared(p(c)) {
            vec![corner, [a, x, y], [a, y, c]]
        } else {
            vec![corner, [a, x, c], [x, y, c]]
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::{HashMap, HashSet};

    use glam::DVec3;

    use crate::color::luminance;
    use crate::gather::tests::square;
    use crate::geometry::kernel::point_to_polygon;
    use crate::pipeline::{self, Outcome, Settings};
    use crate::sampling::Rng;
    use crate::scene::{Scene, SceneBuilder};
    use crate::validation::pointwise::{Display, Probe};
    use crate::validation::scenes;

    /// Receiver ρ, emitter Le, and the blocker's height.
    const RHO: f64 = 0.5;
    const LE: f64 = 2.0;
    const BLOCKER_Z: f64 = 0.1;

    /// A unit square receiver at z = 0 (facing up) under a unit square emitter at z = 1
    /// (facing down, reflecting nothing), with a black blocker at z = 0.1 over x < 0.5 that
    /// reaches far past both in y: a straight penumbra across the receiver.
    fn half_shadow() -> Scene {
        let mut b = SceneBuilder::new();
        let src = b.material("source", [0.0; 3], [LE; 3]);
        let rcv = b.material("receiver", [RHO; 3], [0.0; 3]);
        let wall = b.material("blocker", [0.0; 3], [0.0; 3]);
        let rect = |z: f64, x: [f64; 2], y: [f64; 2], up: bool| {
            let c = [
                DVec3::new(x[0], y[0], z),
                DVec3::new(x[1], y[0], z),
                DVec3::new(x[1], y[1], z),
                DVec3::new(x[0], y[1], z),
            ];
            if up {
                c
            } else {
                [c[0], c[3], c[2], c[1]]
            }
        };
        b.quad(rect(0.0, [0.0, 1.0], [0.0, 1.0], true), rcv);
        b.quad(rect(1.0, [0.0, 1.0], [0.0, 1.0], false), src);
        b.quad(rect(BLOCKER_Z, [-2.0, 0.5], [-2.0, 3.0], false), wall);
        b.build().unwrap()
    }

    /// The exact radiance at receiver point (x, y, 0): ρ·Le·F to the part of the emitter the
    /// blocker leaves visible. The segment to emitter point (e, ·, 1) crosses z = 0.1 at
    /// x + 0.1 (e − x), clear of the blocker when that is ≥ 0.5: e ≥ (0.5 − 0.9 x) / 0.1.
    /// Nothing else reflects, so this is the whole answer (Lambert's contour integral).
    fn exact(p: DVec3) -> f64 {
        let t = BLOCKER_Z;
        let from = ((0.5 - (1.0 - t) * p.x) / t).clamp(0.0, 1.0);
        if from >= 1.0 {
            return 0.0;
        }
        let visible = [
            DVec3::new(from, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(from, 1.0, 1.0),
        ];
        RHO * LE * point_to_polygon(p, DVec3::Z, &visible)
    }

    fn bake(scene: &Scene, tolerance: f64) -> Outcome {
        let settings = Settings {
            refine_rounds: 0,
            gather_tolerance: tolerance,
            ..Settings::default()
        };
        pipeline::solve_scene(scene, &settings).unwrap()
    }

    /// RMS relative error of the displayed (interpolated) luminance at 500 random receiver
    /// points brighter than a tenth of the brightest.
    fn displayed_rms(out: &Outcome) -> f64 {
        let mut rng = Rng::new(&[7]);
        let probes: Vec<Probe> = (0..500)
            .map(|_| {
                let position = DVec3::new(rng.next_f64(), rng.next_f64(), 0.0);
                Probe {
                    triangle: 0,
                    position,
                    normal: DVec3::Z,
                    radiance: [exact(position); 3],
                    std_error: 0.0,
                    paths: 0,
                }
            })
            .collect();
        let shown = Display::from_baked(&out.baked).at(&probes);
        let bright = RHO * LE * 0.1 * exact(DVec3::new(1.0, 0.5, 0.0));
        let (mut sum, mut n) = (0.0, 0);
        for (p, s) in probes.iter().zip(&shown) {
            if p.radiance[0] < bright {
                continue;
            }
            let e = luminance(s.expect("every receiver point is displayed").interpolated)
                / luminance(p.radiance)
                - 1.0;
            sum += e * e;
            n += 1;
        }
        assert!(n > 200, "{n} points scored");
        (sum / n as f64).sqrt()
    }

    #[test]
    fn the_direct_light_in_a_penumbra_is_the_visible_parts_exact_form_factor() {
        // Across the blocker's penumbra, the gather's direct light is ρ·Le·F of the part of
        // the emitter left visible, to rounding and for any seed: the visible pieces
        // (form_factor::visible) cut the blocker's shadow from the emitter exactly, where
        // shadow rays (256 in a penumbra) were off by up to 2 %.
        let scene = half_shadow();
        let patches = crate::mesh::subdivide(&scene, 0.25, 0.0).unwrap();
        let radiance = vec![[0.0; 3]; patches.len()];
        let env = crate::scene::Environment::default();
        let g = super::Gatherer::new(&scene, &patches, &radiance, &env, 1);
        let mut checked = 0;
        for i in (0..patches.len()).filter(|&i| patches.reflectance[i][0] == RHO) {
            let c = patches.corners(i);
            for (u, v) in (1..8).flat_map(|u| (1..8 - u).map(move |v| (u, v))) {
                let (u, v) = (u as f64 / 8.0, v as f64 / 8.0);
                let p = c[0] + u * (c[1] - c[0]) + v * (c[2] - c[0]);
                let want = exact(p);
                for seed in [1, 2] {
                    let mut rng = Rng::new(&[seed, i as u64]);
                    let got = RHO * g.direct(p, DVec3::Z, i as u32, &mut rng)[0];
                    assert!(
                        (got - want).abs() <= 1e-9 * want.max(1e-3),
                        "{p}: {got} against {want}"
                    );
                }
                // In the penumbra: the blocker hides part of the emitter, not all of it.
                let hidden = (0.5 - (1.0 - BLOCKER_Z) * p.x) / BLOCKER_Z;
                checked += (hidden > 0.0 && hidden < 1.0) as usize;
            }
        }
        assert!(checked >= 6, "only {checked} points in the penumbra");
    }

    #[test]
    fn refinement_follows_the_penumbra_and_halves_the_displayed_error() {
        // The patch mesh (edges ~0.34, the scene's diagonal / 16) is coarse against the
        // penumbra (0.11 wide): linear interpolation between gathered vertices misses its
        // shape. The refinement splits edges across it until the direct light is linear to
        // τ = 2 %, within the budget.
        let scene = half_shadow();
        let coarse = bake(&scene, 0.0);
        let fine = bake(&scene, super::DEFAULT_TOLERANCE);
        let (before, after) = (displayed_rms(&coarse), displayed_rms(&fine));
        let added = fine.report.display_refinement.vertices;
        assert_eq!(coarse.report.display_refinement.vertices, 0);
        assert!(added > 0);
        assert_eq!(
            fine.baked.positions.len(),
            coarse.baked.positions.len() + added
        );
        assert!(added <= super::budget(1024, 1), "{added} vertices");
        // Measured 44 % → 1.4 % (1,800 vertices added). What remains is the shadow rays' noise
        // in the penumbra (256 stratified rays, ~1 % a vertex) and the τ left to
        // interpolation: 3 % bounds it with room for another seed.
        assert!(
            after < 0.03 && after < 0.5 * before,
            "RMS {before} → {after}"
        );
        fine.baked.validate().unwrap();
    }

    #[test]
    fn the_cache_gathers_refinement_follows_the_penumbra_with_its_tests_light() {
        // The same penumbra under the `cache` gather, whose new vertices take the direct
        // light their edge's test found at the same point: were a vertex given another
        // point's light, or none, the display would show it across the vertex's star. The
        // budget is half the output's vertices (a finer patch mesh, so that it covers the
        // penumbra). Nothing here is reflected twice (the source and the blocker reflect
        // nothing), so the whole answer is the exact direct light.
        let scene = half_shadow();
        let cached = |tolerance: f64| {
            let settings = Settings {
                refine_rounds: 0,
                max_edge: Some(0.08),
                gather: crate::gather::Gather::Cache,
                gather_tolerance: tolerance,
                ..Settings::default()
            };
            pipeline::solve_scene(&scene, &settings).unwrap()
        };
        let (coarse, fine) = (cached(0.0), cached(super::DEFAULT_TOLERANCE));
        let (before, after) = (displayed_rms(&coarse), displayed_rms(&fine));
        let added = fine.report.display_refinement.vertices;
        assert!(added > 0);
        assert!(
            added as f64 <= super::CACHE_REFINE_SHARE * coarse.baked.positions.len() as f64,
            "{added} vertices added to {}",
            coarse.baked.positions.len()
        );
        // Measured 4.6 % → 0.14 % (905 vertices added to 8,355); with the new vertices given
        // 0.8 × their test's direct light, 7.3 %. The emitter is computed exactly (its visible
        // pieces, no shadow-ray noise), so what remains is interpolation within τ where the
        // light bends: 1 % bounds it with room for another seed.
        assert!(
            after < 0.01 && after < 0.5 * before,
            "RMS {before} → {after}"
        );
        fine.baked.validate().unwrap();
    }

    #[test]
    fn a_tests_direct_light_reads_back_as_written_for_another_rank() {
        // Over several processes the tests are shared out and their findings exchanged: the
        // vertex a rank adds must take, bit for bit, the light another rank's test found.
        use crate::distributed::{Reader, Writer};
        let lit = super::Lit {
            x: DVec3::new(0.1, -2.5e-7, 3.0),
            n: DVec3::new(0.0, 0.6, -0.8),
            patch: 4_000_000_001,
            direct: [1.0 / 3.0, 0.0, f64::MIN_POSITIVE],
            penumbra: true,
            exact: vec![0, 7, 65_535],
        };
        let mut w = Writer::default();
        super::Lit::write(None, &mut w);
        super::Lit::write(Some(&lit), &mut w);
        super::Lit::write(None, &mut w);
        let mut r = Reader::new(&w.0);
        assert!(super::Lit::read(&mut r).is_none());
        let back = super::Lit::read(&mut r).expect("written");
        assert!(super::Lit::read(&mut r).is_none());
        assert_eq!((back.x, back.n, back.patch), (lit.x, lit.n, lit.patch));
        assert_eq!(back.direct.map(f64::to_bits), lit.direct.map(f64::to_bits));
        assert_eq!((back.penumbra, &back.exact), (lit.penumbra, &lit.exact));
    }

    #[test]
    fn a_dark_middle_between_lit_ends_is_split_by_its_indirect_light() {
        // A unit receiver (z = 0, facing up) lit only indirectly: an emitter facing up at
        // z = 0.95 lights a white ceiling at z = 1, which lights the receiver; nothing emits
        // towards the receiver, so its direct light is 0 everywhere. A black plate 0.2 wide
        // hovers 5 mm above the receiver's centre (not a contact: the contact tolerance is
        // 1.7 mm here): under it the receiver sees only a slit 5 mm high, about cos²(87°) =
        // 0.25 % of the ceiling, while the receiver's patch corners (one patch edge across the
        // square) are all open. Only the midpoint test's indirect rays can see the dark middle
        // of the diagonal: the direct light is 0 at its ends and its midpoint.
        let mut b = SceneBuilder::new();
        let white = b.material("white", [0.9; 3], [0.0; 3]);
        let rcv = b.material("receiver", [RHO; 3], [0.0; 3]);
        let src = b.material("source", [0.0; 3], [LE; 3]);
        let black = b.material("black", [0.0; 3], [0.0; 3]);
        b.quad(square(0.0, 0.0, 1.0, 0.0, true), rcv);
        b.quad(square(-1.0, -1.0, 3.0, 1.0, false), white);
        b.quad(square(0.3, 0.3, 0.4, 0.95, true), src);
        b.quad(square(0.4, 0.4, 0.2, 0.005, false), black); // facing the receiver
        let scene = b.build().unwrap();
        let settings = Settings {
            max_edge: Some(2.0),
            refine_rounds: 0,
            ..Settings::default()
        };
        let out = pipeline::solve_scene(&scene, &settings).unwrap();
        let b = &out.baked;
        let under = |p: &[f64; 3]| {
            p[2] == 0.0 && (0.4..=0.6).contains(&p[0]) && (0.4..=0.6).contains(&p[1])
        };
        assert!(
            b.positions.iter().any(under),
            "no output vertex under the plate ({} added)",
            out.report.display_refinement.vertices
        );
        let at = |x: f64, y: f64| Probe {
            triangle: 0,
            position: DVec3::new(x, y, 0.0),
            normal: DVec3::Z,
            radiance: [0.0; 3],
            std_error: 0.0,
            paths: 0,
        };
        let shown = Display::from_baked(b).at(&[at(0.5, 0.5), at(0.15, 0.85)]);
        let y = |k: usize| luminance(shown[k].expect("displayed").interpolated);
        // Under the plate's centre ~0.25 % of the open value (above); a quarter leaves room
        // for the gather's noise and for a vertex a little off the centre.
        assert!(y(0) < 0.25 * y(1), "centre {} against open {}", y(0), y(1));
    }

    #[test]
    fn the_indirect_light_ray_by_ray_finds_a_bright_middle_between_shaded_ends() {
        // A receiver (ρ = 0.5, z = 0, facing up) under the CIE overcast sky, whose radiance
        // falls from the zenith to a third at the horizon, so that what one ray brings varies
        // by a factor of 3. Two black plates, 4 cm square, hover 5 mm above two of its corners
        // (a leg's top under a seat, upside down): at the plates' inner corners they fill
        // most of a quadrant of the hemisphere, and the edge between those two points is
        // about a third darker at its ends than at its open middle. Nothing emits: there is
        // no direct light, and the ends are alike, so only the indirect light's test can
        // find the middle.
        let (side, leg) = (0.45, 0.04);
        let mut b = SceneBuilder::new();
        let rcv = b.material("receiver", [RHO; 3], [0.0; 3]);
        let black = b.material("plate", [0.0; 3], [0.0; 3]);
        b.quad(square(0.0, 0.0, side, 0.0, true), rcv);
        b.quad(square(0.0, 0.0, leg, 0.005, false), black);
        let far = side - leg;
        b.quad(square(far, far, leg, 0.005, false), black);
        let scene = b.build().unwrap();
        let patches = crate::mesh::subdivide(&scene, 0.1, 0.0).unwrap();
        let radiance = vec![[0.0; 3]; patches.len()];
        let env = crate::scene::Environment {
            sky: [1.0; 3],
            sky_model: crate::scene::SkyModel::Overcast,
            up: crate::scene::Up::Z,
            ..crate::scene::Environment::default()
        };
        let gatherer = |seed| crate::gather::Gatherer::new(&scene, &patches, &radiance, &env, seed);
        let at = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let mid = |[a, b]: [DVec3; 2]| 0.5 * (a + b);
        // The oracle: the reflected indirect light by 4,096 rays (its noise ≈ 0.3 %).
        let oracle = gatherer(99);
        let indirect = |x: DVec3| {
            luminance(
                oracle
                    .at_point(x, DVec3::Z, 4096, 7)
                    .expect("on the receiver")
                    .indirect,
            )
        };
        let near = [at(leg, leg), at(side - leg, side - leg)];
        let across = [at(0.1, 0.35), at(0.35, 0.1)];
        let ends = 0.5 * (indirect(near[0]) + indirect(near[1]));
        let between = indirect(mid(near)) - ends;
        // The setting's premise: the middle is far more than τ brighter.
        assert!(between > 0.2 * ends, "{between} over {ends}");
        for seed in 0..16 {
            let g = gatherer(seed);
            let departure = |e: [DVec3; 2]| {
                let [m, a, b] = [mid(e), e[0], e[1]].map(|x| g.spot_at(x, DVec3::Z).unwrap());
                super::correlated_departure(&g, [&m, &a, &b])
            };
            // Found, past τ of the ends' light, and not more than there is: 2 standard
            // errors of the rays' differences come off their mean, which 16 rays leave within
            // a fifth of the truth here (the blocked rays are 4 to 6 of 16, by the jitter).
            let found = departure(near);
            assert!(
                found > super::DEFAULT_TOLERANCE * ends && found < 1.2 * between,
                "seed {seed}: {found} against {between} (τ × ends {})",
                super::DEFAULT_TOLERANCE * ends
            );
            // Across the open middle the light is smooth and the rays agree: nothing found.
            assert_eq!(
                departure(across),
                0.0,
                "seed {seed}: across the open middle"
            );
        }
    }

    #[test]
    fn a_partition_of_two_wall_faces_does_not_darken_the_floor_beside_it() {
        // A closed 2 × 1 × 1 room split at x = 1 … 1.1 by a partition built as architects'
        // models often build one: two wall faces standing on the floor, which runs on under
        // them, so the floor's strip between the faces is walled in by their backs (its normal
        // ray meets the ceiling's front: not buried). A light over the left half. The
        // refinement tests edges across the strip, whose midpoints get no direct light;
        // fitted to them, the contact line's vertices showed the floor beside the partition
        // 15–25 % dark. The floor's vertices on the line must show the light 1 mm beside
        // it (the light is continuous there).
        let mut b = SceneBuilder::new();
        let grey = b.material("grey", [0.5; 3], [0.0; 3]);
        let src = b.material("light", [0.0; 3], [10.0; 3]);
        let v = DVec3::new;
        scenes::add_box(&mut b, DVec3::ZERO, v(2.0, 1.0, 1.0), true, grey);
        for (x, side) in [(1.0, 0), (1.1, 1)] {
            scenes::rectangle(&mut b, v(x, 0.0, 0.0), v(x, 1.0, 1.0), side, grey);
        }
        scenes::rectangle(&mut b, v(0.3, 0.3, 0.99), v(0.7, 0.7, 0.99), 4, src);
        let scene = b.build().unwrap();
        let out = pipeline::solve_scene(&scene, &Settings::default()).unwrap();
        assert!(out.report.display_refinement.vertices > 0);
        let (split, _) = crate::mesh::split_contacts(&scene);
        let env = crate::scene::Environment::default();
        let g = super::Gatherer::new(&split, &out.patches, &out.solution.radiance, &env, 9);
        let baked = &out.baked;
        let at = |v: u32| DVec3::from(baked.positions[v as usize]);
        // The vertices of the lit floor's faces (the strip's own vertices on the line are
        // shown only on the strip, which nobody sees).
        let lit: HashSet<u32> = baked
            .faces
            .iter()
            .filter(|f| {
                f.iter()
                    .all(|&v| at(v).z.abs() < 1e-9 && at(v).x < 1.0 + 1e-6)
            })
            .flatten()
            .copied()
            .collect();
        let mut worst: f64 = 0.0;
        let mut checked = 0;
        for k in lit {
            let p = at(k);
            if (p.x - 1.0).abs() > 1e-6 || !(0.1..=0.9).contains(&p.y) {
                continue;
            }
            let k = k as usize;
            let beside = p - DVec3::new(1e-3, 0.0, 0.0);
            let mut rng = Rng::new(&[3, k as u64]);
            let d = g.direct(beside, DVec3::Z, u32::MAX, &mut rng);
            let exact = g.exact_emitters(beside);
            let i = g.indirect(beside, DVec3::Z, u32::MAX, &exact, 4096, &mut rng);
            let want = 0.5 * luminance(std::array::from_fn(|c| d[c] + i[c]));
            let got = luminance(baked.vertex_radiance[k]);
            worst = worst.max((got / want - 1.0).abs());
            checked += 1;
        }
        assert!(checked >= 4, "{checked} vertices on the contact line");
        // Measured: 0.5 % at worst over 26 vertices (23 % with the strip's midpoints fitted;
        // 7 % at two vertices with ENCLOSED at 75 %). The vertices' own gather (about 1,000
        // rays here) and the local fits move them by about 1 %; 4 % leaves room for another
        // seed and still catches the darkening.
        assert!(worst < 0.04, "a contact vertex {:.1} % off", 100.0 * worst);
    }

    #[test]
    fn refinement_is_the_same_for_any_thread_count() {
        let scene = half_shadow();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| bake(&scene, super::DEFAULT_TOLERANCE))
                .baked
        };
        let one = run(1);
        assert!(one.positions.len() > 100);
        assert_eq!(one, run(3));
    }

    #[test]
    fn refined_mesh_is_conforming() {
        // No T-junction: on the flat receiver every edge inside the square has a face on each
        // side, so an edge with one face lies on the square's outline. A vertex added on one
        // side of an edge only would leave two half-edges and one whole edge with one face
        // each, inside the square.
        let out = bake(&half_shadow(), super::DEFAULT_TOLERANCE);
        assert!(out.report.display_refinement.levels > 1);
        let b = &out.baked;
        let key = |v: u32| b.positions[v as usize].map(f64::to_bits);
        let mut faces_at: HashMap<_, usize> = HashMap::new();
        for f in b
            .faces
            .iter()
            .filter(|f| f.iter().all(|&v| b.positions[v as usize][2] == 0.0))
        {
            for k in 0..3 {
                let (a, c) = (key(f[k]), key(f[(k + 1) % 3]));
                *faces_at
                    .entry(if a < c { (a, c) } else { (c, a) })
                    .or_default() += 1;
            }
        }
        let on_outline = |p: [u64; 3]| {
            let p = p.map(f64::from_bits);
            p[0] == 0.0 || p[0] == 1.0 || p[1] == 0.0 || p[1] == 1.0
        };
        for ((a, c), n) in faces_at {
            let outline = on_outline(a) && on_outline(c) && {
                let (a, c) = (a.map(f64::from_bits), c.map(f64::from_bits));
                a[0] == c[0] || a[1] == c[1]
            };
            assert_eq!(n, if outline { 1 } else { 2 }, "edge {a:?}–{c:?}");
        }
    }
}
