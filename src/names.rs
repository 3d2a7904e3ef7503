//! The names of the enums a user types or a file records (methods, weightings, budgets,
//! quantisations, views...). Each enum derives its names from its variants with strum
//! (`IntoStaticStr`, `Display`, `VariantArray`, kebab-case unless a variant says otherwise), so
//! the name printed and the name parsed cannot drift; [`named!`](crate::named) gives it the one
//! parser, whose error names what was typed and every name it could have been. Where an enum is
//! also in a file, a test holds its serde name to this one.

use strum::VariantArray;

use crate::error::{PrtError, Result};

/// An enum whose values a user names.
pub trait Named: Copy + VariantArray + Into<&'static str> + 'static {
    /// What a value is called in messages ("method", "weighting").
    const WHAT: &'static str;
    /// Other spellings accepted when parsing, each with the value it names.
    const ALIASES: &'static [(&'static str, Self)] = &[];

    /// The value's name, as printed and parsed.
    fn name(self) -> &'static str {
        self.into()
    }
}

/// The value `s` names (or one of its aliases), else an error naming `s` and every name.
pub fn parse<T: Named>(s: &str) -> Result<T> {
    T::VARIANTS
        .iter()
        .copied()
        .find(|v| v.name() == s)
        .or_else(|| T::ALIASES.iter().find(|(a, _)| *a == s).map(|(_, v)| *v))
        .ok_or_else(|| PrtError::invalid(T::WHAT, format!("`{s}`; expected {}", listed::<T>())))
}

/// Every name of `T`, as "a, b or c".
pub fn listed<T: Named>() -> String {
    let names: Vec<&str> = T::VARIANTS.iter().map(|v| v.name()).collect();
    match names.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// What a lookup by name could have found, for its error: `none` where there is nothing, else
/// `some` followed by the names, comma-separated ("it has a, b").
pub fn known<'a>(names: impl IntoIterator<Item = &'a str>, none: &str, some: &str) -> String {
    let names: Vec<&str> = names.into_iter().collect();
    if names.is_empty() {
        none.to_string()
    } else {
        format!("{some} {}", names.join(", "))
    }
}

/// Makes an enum [`Named`] under `what` (with optional aliases) and parses it from a string
/// through [`parse`]: `named!(Method, "method");`, `named!(Weighting, "weighting",
/// ["unweighted" => Weighting::Unweighted]);`.
#[macro_export]
macro_rules! named {
    ($t:ty, $what:literal $(, [$($alias:literal => $value:expr),* $(,)?])?) => {
        impl $crate::names::Named for $t {
            const WHAT: &'static str = $what;
            $(const ALIASES: &'static [(&'static str, Self)] = &[$(($alias, $value)),*];)?
        }

        impl std::str::FromStr for $t {
            type Err = $crate::error::PrtError;
            fn from_str(s: &str) -> $crate::error::Result<Self> {
                $crate::names::parse(s)
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(
        Clone,
        Copy,
        Debug,
        PartialEq,
        strum::IntoStaticStr,
        strum::Display,
        strum::VariantArray
    )]
    #[strum(serialize_all = "kebab-case")]
    enum Shade {
        Light,
        DarkGrey,
        #[strum(serialize = "none")]
        Nothing,
    }
    crate::named!(Shade, "shade", ["no" => Shade::Nothing]);

    #[test]
    fn names_parse_back_aliases_too_and_a_stranger_is_told_every_name() {
        for v in Shade::VARIANTS {
            assert_eq!(v.name().parse::<Shade>().unwrap(), *v);
            assert_eq!(v.to_string(), v.name());
        }
        assert_eq!(Shade::DarkGrey.name(), "dark-grey");
        assert_eq!("no".parse::<Shade>().unwrap(), Shade::Nothing);
        let e = "grey".parse::<Shade>().unwrap_err().to_string();
        assert!(e.contains("shade") && e.contains("`grey`"), "{e}");
        assert!(e.contains("light, dark-grey or none"), "{e}");
    }

    /// The name a file records (serde) is the one printed and parsed.
    fn agrees_with_serde<T: Named + serde::Serialize>() {
        for v in T::VARIANTS {
            let recorded = serde_json::to_value(v).expect("serialises");
            assert_eq!(recorded.as_str(), Some(v.name()), "{}", T::WHAT);
        }
    }

    #[test]
    fn names_in_files_are_the_names_users_type() {
        agrees_with_serde::<crate::store::budget::Budget>();
        agrees_with_serde::<crate::store::quant::Quantization>();
        agrees_with_serde::<crate::store::transport::BounceVisibility>();
    }
}
