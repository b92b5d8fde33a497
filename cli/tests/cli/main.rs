//! The command line's test binary: the `radiosity` binary run end to end, one file per command
//! or concern. What belongs here: anything a user sees through the binary (files written,
//! messages, exit statuses); library behaviour is tested in the root package's tests/ and unit
//! tests, and `--help` against the README's option tables in the binary's own unit tests
//! (`cli/src/args.rs`).
//!
//! - `bake`, `render`, `info`: each command end to end;
//! - `options`: options shared by the commands (material overrides, progress, verbosity);
//! - `errors`: bad input of every kind: exit status, message, nothing lost;
//! - `camera`, `two_sided`, `ply_input`: the scene's camera, `--two-sided`, PLY scenes;
//! - `lights`: `--sky`, `--sun`, point and spot lights, a lights file, and `--up`;
//! - `golden`: every output byte-identical to the recorded one.

mod bake;
mod camera;
mod errors;
mod golden;
mod info;
mod lights;
mod options;
mod ply_input;
mod render;
mod support;
mod two_sided;
