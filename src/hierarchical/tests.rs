//! Unit tests of the hierarchical solver.
