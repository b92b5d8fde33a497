//! What the binary says when something fails, and its exit status. The library names its
//! settings in its own words (`max_edge`, `form_factors.samples`, …, see
//! [`radiosity::Error::Setting`]); this module maps them back to the flags that set them, so a
//! user reads `invalid value for --max-edge: …`. A mistake only the command line can make (a
//! flag value clap cannot check, an option that does not apply) is a [`Failure::Usage`].
//! Exit statuses: 0 success, 1 internal failure, 2 bad input or usage, 3 the solver stopped at
//! --max-iterations without converging (the output is written).

use std::fmt;

use radiosity::Error;

/// Exit status of bad input or usage.
pub const EXIT_USAGE: u8 = 2;

/// Exit status when the solver did not converge (the output is still written).
pub const EXIT_NOT_CONVERGED: u8 = 3;

/// The library's setting names and the flags that set them.
pub const FLAGS: [(&str, &str); 42] = [
    ("method", "--method"),
    ("hierarchical.epsilon", "--epsilon"),
    ("hierarchical.min_area", "--min-area"),
    ("hierarchical.rays", "--link-rays"),
    ("hierarchical.max_passes", "--max-passes"),
    ("hierarchical.max_links", "--max-memory"),
    ("max_edge", "--max-edge"),
    ("crease_degrees", "--crease"),
    ("refine_rounds", "--refine"),
    ("refine_threshold", "--refine-threshold"),
    ("refine_max_patches", "--refine-max-patches"),
    ("max_memory", "--max-memory"),
    ("max_time", "--max-time"),
    ("environment.sky", "--sky"),
    ("environment.sun", "--sun"),
    ("environment.sky_model", "--sky-model"),
    ("environment.point_lights", "--point-light"),
    ("environment.spot_lights", "--spot-light"),
    ("view.up", "--up"),
    ("form_factors.estimator", "--form-factors"),
    ("form_factors.samples", "--samples"),
    ("form_factors.rays", "--rays"),
    ("solver.method", "--solver"),
    ("solver.tolerance", "--tolerance"),
    ("solver.max_iterations", "--max-iterations"),
    ("solver.omega", "--omega"),
    ("solver.bounces", "--bounces"),
    ("exposure", "--exposure"),
    ("view.size", "--size"),
    ("view.spp", "--spp"),
    ("camera", "--camera"),
    ("reflectance", "--reflectance"),
    ("emission", "--emission"),
    ("output", "--output"),
    ("report", "--report"),
    ("png", "--png"),
    ("cache", "--cache"),
    ("gather", "--gather"),
    ("discontinuities", "--discontinuities"),
    ("gather_rays", "--gather-rays"),
    ("gather_tolerance", "--gather-tolerance"),
    ("display_budget", "--display-budget"),
];

/// The flag that sets the library's setting `name`, if there is one.
pub fn flag(name: &str) -> Option<&'static str> {
    FLAGS.iter().find(|(n, _)| *n == name).map(|(_, f)| *f)
}

/// Why a command failed.
#[derive(Debug)]
pub enum Failure {
    /// The library's error.
    Library(Error),
    /// A usage mistake the command line catches itself: the flag and what is wrong.
    Usage { flag: &'static str, message: String },
}

impl Failure {
    /// A usage mistake with `flag`.
    pub fn usage(flag: &'static str, message: impl Into<String>) -> Failure {
        Failure::Usage {
            flag,
            message: message.into(),
        }
    }

    /// The process exit status: the library's ([`Error::exit_code`]) or 2 for usage.
    pub fn exit_code(&self) -> u8 {
        match self {
            Failure::Library(e) => e.exit_code() as u8,
            Failure::Usage { .. } => EXIT_USAGE,
        }
    }

    /// The chain of causes below the message, outermost first.
    pub fn causes(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Failure::Library(e) = self {
            let mut source = std::error::Error::source(e);
            while let Some(s) = source {
                out.push(s.to_string());
                source = s.source();
            }
        }
        out
    }
}

impl From<Error> for Failure {
    fn from(e: Error) -> Failure {
        Failure::Library(e)
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::Library(Error::Setting { name, message }) => match flag(name) {
                Some(flag) => write!(f, "invalid value for {flag}: {message}"),
                None => write!(f, "invalid {name}: {message}"),
            },
            Failure::Library(e) => write!(f, "{e}"),
            Failure::Usage { flag, message } => write!(f, "invalid value for {flag}: {message}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn every_mapped_flag_exists_and_settings_read_as_flags() {
        let cli = crate::args::Cli::command();
        let flags: Vec<String> = cli
            .get_subcommands()
            .flat_map(|c| c.get_arguments())
            .chain(cli.get_arguments())
            .filter_map(|a| a.get_long().map(|l| format!("--{l}")))
            .collect();
        for (name, flag) in FLAGS {
            assert!(
                flags.iter().any(|f| f == flag),
                "{name} → {flag}: no such flag"
            );
        }
        let e = Failure::from(Error::setting("form_factors.samples", "must be at least 1"));
        assert_eq!(
            e.to_string(),
            "invalid value for --samples: must be at least 1"
        );
        assert_eq!(e.exit_code(), 2);
        let e = Failure::from(Error::setting("unmapped", "x"));
        assert_eq!(e.to_string(), "invalid unmapped: x");
        let e = Failure::from(Error::Internal("bug".into()));
        assert_eq!(e.exit_code(), 1);
    }
}
