//! Parsing a choice by name (`FromStr` of the configuration enums), with the one error
//! every front end shows: "`x` is not one of a, b, c".

/// The value named `name` in `table` (`(name, value)` pairs; the first `listed` names are
/// the canonical ones the error lists, the rest older spellings still accepted).
pub(crate) fn parse<T: Copy>(name: &str, table: &[(&str, T)], listed: usize) -> Result<T, String> {
    table.iter().find(|(n, _)| *n == name).map(|(_, v)| *v).ok_or_else(|| {
        let names: Vec<&str> = table.iter().take(listed).map(|(n, _)| *n).collect();
        format!("`{name}` is not one of {}", names.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use crate::calibration::{Extrapolation, ModelKind};
    use crate::psd::{Detrend, Scaling};

    #[test]
    fn names_and_the_error_listing_them() {
        assert_eq!("speed-table".parse::<ModelKind>(), Ok(ModelKind::SpeedTable));
        assert_eq!("speed_table".parse::<ModelKind>(), Ok(ModelKind::SpeedTable));
        assert_eq!(
            "table".parse::<ModelKind>().unwrap_err(),
            "`table` is not one of gain, static, dynamic, speed-table, speed-poly"
        );
        assert_eq!("reject".parse::<Extrapolation>(), Ok(Extrapolation::Reject));
        assert_eq!("hold".parse::<Extrapolation>().unwrap_err(), "`hold` is not one of clamp, linear, reject");
        assert_eq!("none".parse::<Detrend>(), Ok(Detrend::None));
        assert_eq!("mean".parse::<Detrend>().unwrap_err(), "`mean` is not one of constant, linear, none");
        assert_eq!("psd".parse::<Scaling>().unwrap_err(), "`psd` is not one of density, spectrum");
    }
}
