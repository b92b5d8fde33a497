//! A bake over several ranks ([`radiosity::distributed`]) through the whole pipeline, with the
//! ranks as threads of this process: the same output, to the bit, as one process, for the
//! hierarchical solve (shared by links), the matrix method (run whole on every rank) and the
//! gather and its display refinement (shared by vertices). The same check through MPI is
//! `tools/mpi_check.sh`, which `.ci/run` runs under `mpirun`.

use radiosity::distributed::Threads;
use radiosity::gather::Gather;
use radiosity::pipeline::{self, Method, Outcome};
use radiosity::scene::Scene;
use radiosity::validation::scenes;

/// `scene` baked with `settings` over `n` thread ranks: every rank's outcome.
fn over_ranks(scene: &Scene, settings: &pipeline::Settings, n: usize) -> Vec<Outcome> {
    let prepared = pipeline::prepare(scene, settings);
    Threads::run(n, |comm| {
        pipeline::solve_prepared_on(&prepared, settings, comm).unwrap()
    })
}

/// The bits of what a bake shows: its vertices' positions and radiance.
fn shown(out: &Outcome) -> (Vec<u64>, Vec<u64>) {
    let bits = |x: &[[f64; 3]]| x.iter().flatten().map(|v| v.to_bits()).collect();
    (bits(&out.baked.positions), bits(&out.baked.vertex_radiance))
}

/// The living room lit by its two lamps, both methods, with the gather and its
/// display refinement: 2 and 3 ranks show what one process shows, bit for bit, on every rank.
/// No tolerance: every value is computed by one rank exactly as one process computes it.
#[test]
fn a_bake_over_several_ranks_shows_what_one_process_shows_to_the_bit() {
    let scene = scenes::living_room().unwrap();
    for method in [Method::Hierarchical, Method::Matrix] {
        let mut settings = pipeline::Settings {
            method,
            max_edge: Some(1.0),
            gather: Gather::Full,
            ..pipeline::Settings::default()
        };
        // A small display refinement (a coarse tolerance): its tests and new vertices are
        // shared among the ranks too.
        settings.gather_rays = Some(16);
        settings.gather_tolerance = 0.3;
        let one = pipeline::solve_scene(&scene, &settings).unwrap();
        assert!(
            one.report.display_refinement.vertices > 0,
            "{method:?}: the display was refined"
        );
        for n in [2, 3] {
            for (rank, out) in over_ranks(&scene, &settings, n).iter().enumerate() {
                assert!(
                    shown(out) == shown(&one),
                    "{method:?}, rank {rank} of {n}: the bake differs"
                );
            }
        }
    }
}
