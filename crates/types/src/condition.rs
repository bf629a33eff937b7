//! Perturbation conditions: a name, a family and a level.
//!
//! The envelope paper's grid has short names that parse to a family and a level:
//!
//! | name | family | level |
//! |---|---|---|
//! | `noise_<σ>` (e.g. `noise_30`) | `gaussian_noise` | σ on the 0–255 scale |
//! | `dark` | `brightness` | gain 0.4 |
//! | `bright` | `brightness` | gain 1.6 |
//! | `fog_<α·10, two digits>` (e.g. `fog_07`) | `fog` | α (0.7) |
//!
//! Any other name needs an explicit family and level.

use std::fmt;

use serde::{Deserialize, Serialize};

/// A family of perturbations whose levels are ordered by severity.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(into = "String", from = "String")]
pub enum Family {
    /// Additive Gaussian noise; level σ on the 0–255 scale; identity at 0.
    GaussianNoise,
    /// Photometric gain; level is the factor; identity at 1.
    Brightness,
    /// Fog; level α (opacity) in [0, 1]; identity at 0.
    Fog,
    /// Any other family, named by the user; level ascending means more severe, identity 0.
    Other(String),
}

impl Family {
    /// Parses a family name; unknown names become [`Family::Other`].
    pub fn from_name(name: &str) -> Self {
        match name {
            "gaussian_noise" | "noise" => Self::GaussianNoise,
            "brightness" | "photometric" => Self::Brightness,
            "fog" => Self::Fog,
            other => Self::Other(other.to_string()),
        }
    }

    /// The canonical name of the family.
    pub fn name(&self) -> &str {
        match self {
            Self::GaussianNoise => "gaussian_noise",
            Self::Brightness => "brightness",
            Self::Fog => "fog",
            Self::Other(s) => s,
        }
    }

    /// The level at which the family leaves a frame unchanged.
    pub fn identity_level(&self) -> f64 {
        match self {
            Self::Brightness => 1.0,
            _ => 0.0,
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl From<Family> for String {
    fn from(f: Family) -> String {
        f.name().to_string()
    }
}

impl From<String> for Family {
    fn from(s: String) -> Family {
        Family::from_name(&s)
    }
}

/// A perturbation condition: its name as written in the data, its family and its level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Condition {
    /// The name as written in the data (`noise_30`, `dark`, …).
    pub name: String,
    /// The family it belongs to.
    pub family: Family,
    /// Its level within the family (σ, gain, α, …).
    pub level: f64,
}

/// Why a condition name could not be parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownCondition(pub String);

impl fmt::Display for UnknownCondition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "condition {:?} is not one of noise_<sigma>, dark, bright, fog_<alpha*10 as two digits>; \
             give `family` and `level` columns for other names",
            self.0
        )
    }
}

impl std::error::Error for UnknownCondition {}

impl Condition {
    /// Parses the paper's condition names (see the module docs).
    pub fn parse(name: &str) -> Result<Self, UnknownCondition> {
        let bad = || UnknownCondition(name.to_string());
        let (family, level) = match name {
            "dark" => (Family::Brightness, 0.4),
            "bright" => (Family::Brightness, 1.6),
            _ => {
                if let Some(rest) = name.strip_prefix("noise_") {
                    let sigma: f64 = rest.parse().map_err(|_| bad())?;
                    if !sigma.is_finite() || sigma < 0.0 || rest.starts_with('+') {
                        return Err(bad());
                    }
                    (Family::GaussianNoise, sigma)
                } else if let Some(rest) = name.strip_prefix("fog_") {
                    if rest.len() != 2 || !rest.bytes().all(|b| b.is_ascii_digit()) {
                        return Err(bad());
                    }
                    let tenths: u32 = rest.parse().map_err(|_| bad())?;
                    if tenths > 10 {
                        return Err(bad());
                    }
                    (Family::Fog, f64::from(tenths) / 10.0)
                } else {
                    return Err(bad());
                }
            }
        };
        Ok(Self {
            name: name.to_string(),
            family,
            level,
        })
    }

    /// A condition with an explicit family and level.
    pub fn new(name: impl Into<String>, family: Family, level: f64) -> Self {
        Self {
            name: name.into(),
            family,
            level,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_paper_grid() {
        for (name, fam, lvl) in [
            ("noise_10", Family::GaussianNoise, 10.0),
            ("noise_70", Family::GaussianNoise, 70.0),
            ("noise_2.5", Family::GaussianNoise, 2.5),
            ("dark", Family::Brightness, 0.4),
            ("bright", Family::Brightness, 1.6),
            ("fog_03", Family::Fog, 0.3),
            ("fog_07", Family::Fog, 0.7),
            ("fog_10", Family::Fog, 1.0),
        ] {
            let c = Condition::parse(name).unwrap();
            assert_eq!((c.family, c.level), (fam, lvl), "{name}");
        }
    }

    #[test]
    fn rejects_other_names() {
        for name in [
            "",
            "noise_",
            "noise_x",
            "noise_-3",
            "noise_NaN",
            "noise_inf",
            "fog_3",
            "fog_7a",
            "fog_11",
            "blur_3",
            "clean",
        ] {
            assert!(Condition::parse(name).is_err(), "{name}");
        }
    }

    #[test]
    fn family_round_trips_through_json() {
        let json = serde_json::to_string(&Family::Fog).unwrap();
        assert_eq!(json, "\"fog\"");
        let back: Family = serde_json::from_str("\"motion_blur\"").unwrap();
        assert_eq!(back, Family::Other("motion_blur".into()));
    }
}
