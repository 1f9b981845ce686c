//! Built-in scenarios: the Taghirad and embedded-sensor rigs.

use crate::error::SimError;
use crate::scenario::Scenario;

/// `(name, TOML text)` of every preset.
pub const PRESETS: &[(&str, &str)] = &[
    ("taghirad", include_str!("../presets/taghirad.toml")),
    ("taghirad-standstill", include_str!("../presets/taghirad-standstill.toml")),
    ("taghirad-loaded", include_str!("../presets/taghirad-loaded.toml")),
    ("taghirad-commissioning", include_str!("../presets/taghirad-commissioning.toml")),
    ("flexspline-fixed", include_str!("../presets/flexspline-fixed.toml")),
    ("flexspline-fixed-commissioning", include_str!("../presets/flexspline-fixed-commissioning.toml")),
    ("flexspline-fixed-static", include_str!("../presets/flexspline-fixed-static.toml")),
    ("flexspline-fixed-dynamic", include_str!("../presets/flexspline-fixed-dynamic.toml")),
];

/// The commented TOML of a preset.
pub fn preset_text(name: &str) -> Result<&'static str, SimError> {
    PRESETS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, t)| *t)
        .ok_or_else(|| SimError::UnknownPreset(name.to_string(), preset_names()))
}

/// A preset, parsed and validated.
///
/// ```
/// let s = strainwave_sim::presets::preset("taghirad").unwrap();
/// assert_eq!(s.gear.ratio, 100.0);
/// assert!(strainwave_sim::presets::preset("nope").is_err());
/// ```
pub fn preset(name: &str) -> Result<Scenario, SimError> {
    Scenario::from_toml(preset_text(name)?)
}

/// Comma-separated preset names.
pub fn preset_names() -> String {
    PRESETS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_round_trip() {
        for (name, _) in PRESETS {
            let s = preset(name).unwrap();
            let again = Scenario::from_toml(&s.to_toml()).unwrap();
            assert_eq!(s, again, "{name}");
        }
    }

    #[test]
    fn snake_spellings_of_values_still_load() {
        let text = preset_text("taghirad").unwrap();
        assert!(text.contains("\"four-rosettes\"") && text.contains("\"small-strain\""));
        let old =
            text.replace("\"four-rosettes\"", "\"four_rosettes\"").replace("\"small-strain\"", "\"small_strain\"");
        assert_eq!(Scenario::from_toml(&old).unwrap(), preset("taghirad").unwrap());
        let old = text.replace("\"circular_spline\"", "\"circular-spline\"");
        assert_eq!(Scenario::from_toml(&old).unwrap(), preset("taghirad").unwrap());
    }

    #[test]
    fn an_unknown_value_names_its_key_and_the_accepted_ones() {
        let text = preset_text("taghirad").unwrap().replace("\"four-rosettes\"", "\"six_rosettes\"");
        let e = Scenario::from_toml(&text).unwrap_err().to_string();
        assert!(e.starts_with("`sensor.layout`: unknown variant `six_rosettes`"), "{e}");
        assert!(e.contains("`four-rosettes`") && e.contains("`eight-gauge-t`") && !e.contains('\n'), "{e}");
    }
}
