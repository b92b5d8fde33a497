//! What controls the form-factor estimation: the [`Estimator`], its sample counts and seed,
//! and the [`Shortcuts`] that save work (or trade a little accuracy for time), each of which
//! can be turned off to measure what it saves. [`Settings::validate`] checks the ranges.

use std::fmt;

use serde::Serialize;

use crate::choice::Choice;
use crate::{Error, Result};

/// Which estimator of F_ij to use; see the module documentation of [`crate::form_factor`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// Point pairs with the kernel G·V (near pairs analytic).
    Area,
    /// Exact point-to-polygon integrand × ray visibility.
    Contour,
    /// Cosine-weighted rays from each patch; the first hit names the receiving patch.
    Hemisphere,
}

impl Choice for Estimator {
    const SETTING: &'static str = "form_factors.estimator";
    const ALL: &'static [Estimator] = &[Estimator::Area, Estimator::Contour, Estimator::Hemisphere];

    fn name(self) -> &'static str {
        match self {
            Estimator::Area => "area",
            Estimator::Contour => "contour",
            Estimator::Hemisphere => "hemisphere",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Estimator::Area => "Point pairs with the kernel G·V (near pairs analytic)",
            Estimator::Contour => "Exact point-to-polygon integrand × ray visibility",
            Estimator::Hemisphere => {
                "Cosine-weighted rays from each patch; the first hit names the receiving patch"
            }
        }
    }
}

impl fmt::Display for Estimator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The work-saving shortcuts of the estimation, as one value: each is on by default
/// ([`Shortcuts::all`]), and [`Shortcuts::none`] (or a single field set to `false`) turns them
/// off to measure what each saves or to check that it changes nothing it should not.
///
/// Four change no result, only the work: `skip_hull`, `cull_behind`, `reuse` (up to one f32
/// rounding) and `skip_unneeded` (entries the solve never reads). Three change F within the
/// estimator's error, each for a reason given at the field: `normalise_closed`,
/// `exact_direct`, `far_field`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Shortcuts {
    /// Leave the faces that lie on the scene's convex hull out of the occlusion tests
    /// ([`super::occluders`]): they cannot block a segment between two scene points. In a
    /// convex enclosure (a sphere, an empty room) that is every face, and no visibility ray is
    /// cast at all.
    pub skip_hull: bool,
    /// Normalise the rows of a closed scene to 1 (pair estimators; see [`super::compute`]):
    /// energy conservation made exact; off, the estimators' raw row error shows.
    pub normalise_closed: bool,
    /// Hemisphere shooting: compute the emitters' columns (direct light) with the contour
    /// estimator instead of counting rays, when emitters are a small part of the scene
    /// ([`super::EXACT_DIRECT_FRACTION`], [`super::EXACT_DIRECT_PAIRS`]). A small light is hit
    /// by few of a patch's rays, so shot direct light is the noisiest part of the estimate;
    /// computed exactly it costs emitters × patches pairs.
    pub exact_direct: bool,
    /// Contour estimator: integrate far pairs' sources with the Gauss rule instead of the
    /// exact contour integral ([`super::pair::FAR_FIELD_FACTOR`]): a third of the cost, rows
    /// unchanged to 1e-4.
    pub far_field: bool,
    /// Skip, without a ray, every pair where one patch lies wholly behind the other's plane
    /// (they cannot exchange light).
    pub cull_behind: bool,
    /// Adaptive refinement: keep the entries of pairs of patches a round left unchanged
    /// instead of computing them again ([`super::Reuse`]).
    pub reuse: bool,
    /// Compute only the entries the solve reads ([`super::Needed::for_solve`]: no rows for
    /// black patches, only emitters' columns for one bounce).
    pub skip_unneeded: bool,
}

impl Shortcuts {
    /// Every shortcut on: the default.
    pub const fn all() -> Shortcuts {
        Shortcuts {
            skip_hull: true,
            normalise_closed: true,
            exact_direct: true,
            far_field: true,
            cull_behind: true,
            reuse: true,
            skip_unneeded: true,
        }
    }

    /// Every shortcut off: the estimators as the literature states them, every entry computed.
    pub const fn none() -> Shortcuts {
        Shortcuts {
            skip_hull: false,
            normalise_closed: false,
            exact_direct: false,
            far_field: false,
            cull_behind: false,
            reuse: false,
            skip_unneeded: false,
        }
    }
}

impl Default for Shortcuts {
    fn default() -> Self {
        Shortcuts::all()
    }
}

/// Settings of the form-factor estimation.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Settings {
    /// The estimator.
    pub estimator: Estimator,
    /// Sample points per patch and visibility rays per patch pair (area, contour); ≥ 1.
    pub samples: u32,
    /// Rays per patch (hemisphere); ≥ 1.
    pub rays: u32,
    /// Enforce reciprocity afterwards ([`super::symmetric_part`]): the two estimates of each
    /// exchange A_i F_ij = A_j F_ji are averaged (halving their variance) and the result
    /// rescaled so that every row keeps its sum. Off by default: the averaging moves light
    /// between neighbouring patches by the estimators' reciprocity error (up to ~10 % on small
    /// patches next to contact lines), which the unsymmetrised F does not.
    pub reciprocity: bool,
    /// Seed of every random choice; the same seed gives the same F for any thread count.
    pub seed: u64,
    /// The work-saving shortcuts; all on by default.
    pub shortcuts: Shortcuts,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            estimator: Estimator::Contour,
            samples: 3,
            rays: 1024,
            seed: 1,
            reciprocity: false,
            shortcuts: Shortcuts::all(),
        }
    }
}

impl Settings {
    /// Checks the ranges before any work: `samples` and `rays` at least 1. Errors are
    /// [`Error::Setting`] named `form_factors.samples` / `form_factors.rays`.
    pub fn validate(&self) -> Result<()> {
        if self.samples == 0 {
            return Err(Error::setting("form_factors.samples", "must be at least 1"));
        }
        if self.rays == 0 {
            return Err(Error::setting("form_factors.rays", "must be at least 1"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_and_validation() {
        assert_eq!(Shortcuts::default(), Shortcuts::all());
        assert_ne!(Shortcuts::all(), Shortcuts::none());
        Settings::default().validate().unwrap();
        for (samples, rays, name) in [(0, 8, "form_factors.samples"), (3, 0, "form_factors.rays")] {
            let s = Settings {
                samples,
                rays,
                ..Settings::default()
            };
            match s.validate().unwrap_err() {
                Error::Setting { name: n, .. } => assert_eq!(n, name),
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(
            Estimator::parse("hemisphere").unwrap(),
            Estimator::Hemisphere
        );
        let e = Estimator::parse("sphere").unwrap_err().to_string();
        assert!(e.contains("area, contour, hemisphere"), "{e}");
    }
}
