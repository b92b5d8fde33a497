//! Settings with a fixed set of named values (the form-factor estimator, the solver method):
//! each value's name (what a command line or a report spells) and a one-line description, so
//! that a program built on the library can offer the choices without repeating them.

use crate::error::{Error, Result};

/// An enumerated setting: every value, its name and its description.
pub trait Choice: Copy + Eq + 'static {
    /// Every value, in the order they are listed.
    const ALL: &'static [Self];

    /// The setting's name in the library (`form_factors.estimator`), for errors.
    const SETTING: &'static str;

    /// The value's name: lower case, words joined by `-` (`gauss-seidel`).
    fn name(self) -> &'static str;

    /// One line on what the value does.
    fn description(self) -> &'static str;

    /// The value called `name` (exactly), if there is one.
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.name() == name)
    }

    /// The names of every value, for messages ("one of area, contour, hemisphere").
    fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|c| c.name()).collect()
    }

    /// The value called `name`, or an [`Error::Setting`] listing the names.
    fn parse(name: &str) -> Result<Self> {
        Self::from_name(name).ok_or_else(|| {
            Error::setting(
                Self::SETTING,
                format!("{name:?} is not one of {}", Self::names().join(", ")),
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::Choice;
    use crate::form_factor::Estimator;
    use crate::solve::Method;

    fn round_trip<T: Choice + std::fmt::Debug + std::fmt::Display>() {
        let names = T::names();
        for &c in T::ALL {
            assert_eq!(T::from_name(c.name()), Some(c));
            assert_eq!(c.to_string(), c.name());
            assert!(!c.description().is_empty());
            assert!(c.name().chars().all(|x| x.is_ascii_lowercase() || x == '-'));
        }
        let mut unique = names.clone();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "names are distinct: {names:?}");
        assert_eq!(T::from_name("no-such-value"), None);
        let e = T::parse("No-Such").unwrap_err().to_string();
        assert!(e.contains(T::SETTING) && e.contains(names[0]), "{e}");
    }

    #[test]
    fn every_value_round_trips_through_its_name() {
        round_trip::<Estimator>();
        round_trip::<Method>();
    }
}
