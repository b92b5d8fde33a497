//! `mpirun -n N radiosity bake …`: one bake over N processes, with the `mpi` feature (rsmpi over
//! the system's MPI, Open MPI on Debian). This module starts MPI and gives the library its
//! [`Exchange`] over the world communicator; the library decides what is exchanged
//! ([`radiosity::distributed`]).
//!
//! Only the main thread calls MPI (the library calls its collectives between parallel
//! sections, never inside them), so MPI is started at the `Funneled` level.

use mpi::datatype::PartitionMut;
use mpi::environment::{Threading, Universe};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use radiosity::distributed::{Exchange, Parts};

/// MPI, started: the world's ranks. Dropping it finalizes MPI.
pub struct Mpi {
    world: SimpleCommunicator,
    rank: usize,
    size: usize,
    // Last: dropped after `world`.
    _universe: Universe,
}

// SAFETY: the communicator is a handle MPI owns; `Exchange` is `Sync` only so that the
// solver's parallel sections can hold a reference to it. They never call it: every
// collective is called by the main thread, as MPI's `Funneled` level requires.
unsafe impl Sync for Mpi {}

impl Mpi {
    /// Starts MPI (as a single rank when the program was not started by `mpirun`).
    pub fn start() -> Result<Mpi, String> {
        let (universe, _) =
            mpi::initialize_with_threading(Threading::Funneled).ok_or("MPI was started twice")?;
        let world = universe.world();
        Ok(Mpi {
            rank: world.rank() as usize,
            size: world.size() as usize,
            world,
            _universe: universe,
        })
    }

    /// Ends every rank's process with exit status `code` (MPI_Abort): a rank that fails
    /// must not leave the others waiting in a collective.
    pub fn abort(&self, code: u8) -> ! {
        self.world.abort(code as i32)
    }

    /// The ranks on this machine (Open MPI's or MPICH's count), to share its cores among.
    pub fn local_ranks() -> usize {
        ["OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS"]
            .iter()
            .find_map(|v| std::env::var(v).ok()?.parse().ok())
            .unwrap_or(1)
    }
}

impl Exchange for Mpi {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn all_gather(&self, mine: &[u8]) -> Parts {
        // MPI counts in `int`s: an exchange of 2 GiB or more in all is beyond one call.
        let too_large = || -> ! {
            panic!(
                "an exchange between ranks of 2 GiB or more (a rank sends {} bytes); \
                 such a bake needs fewer elements per rank than this",
                mine.len()
            )
        };
        let n = Count::try_from(mine.len()).unwrap_or_else(|_| too_large());
        let mut counts = vec![0 as Count; self.size];
        self.world.all_gather_into(&n, &mut counts[..]);
        let mut displs = Vec::with_capacity(self.size);
        let mut total: Count = 0;
        for &c in &counts {
            displs.push(total);
            total = total.checked_add(c).unwrap_or_else(|| too_large());
        }
        // An empty slice's pointer is 1, which Open MPI reads as MPI_IN_PLACE: both buffers
        // point into real allocations, however short.
        let one = [0u8; 1];
        let send = if mine.is_empty() { &one[..0] } else { mine };
        let mut buf = vec![0u8; total as usize + 1];
        {
            let recv = &mut buf[..total as usize];
            let mut partition = PartitionMut::new(recv, &counts[..], &displs[..]);
            self.world.all_gather_varcount_into(send, &mut partition);
        }
        buf.truncate(total as usize);
        let ends = displs
            .iter()
            .zip(&counts)
            .map(|(&d, &c)| (d + c) as usize)
            .collect();
        Parts::new(buf, ends)
    }
}
