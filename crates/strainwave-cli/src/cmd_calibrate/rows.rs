//! Errors of the fits with the row given as the user's file and data row.
//!
//! `calibrate` fits the rows of every input together (static, dynamic and speed
//! models) or one experiment at a time (gain, `--held`). The library names a row of the
//! data it was handed, 0-based: with several inputs, `--experiment-column` or `--held`,
//! that is neither a file nor a row the user could find. This turns such a row into the
//! file and its data row (1-based, as users count, the same before and after `--held`).

use anyhow::anyhow;
use strainwave_analysis::calibration::CalibrationError;

use super::ExperimentRows;

/// The column names as the user wrote them, to name a column in a message.
pub struct Columns<'a> {
    /// `--reference`.
    pub reference: &'a str,
    /// `--sensor`.
    pub sensor: &'a str,
    /// `--speed`, if given.
    pub speed: Option<&'a str>,
}

impl Columns<'_> {
    /// The user's words for a column the library names by its role.
    fn describe(&self, library_column: &str) -> String {
        match library_column {
            "reference_nm" | "reference_torque_nm" | "torque_nm" => format!("column `{}`", self.reference),
            "sensor" | "sensor_v" | "indication" => format!("column `{}`", self.sensor),
            "speed_rad_s" => format!("column `{}`", self.speed.unwrap_or("speed")),
            "calibrated_nm" => format!("the calibrated torque (column `{}` through the fit)", self.sensor),
            other => format!("`{other}`"),
        }
    }
}

/// Where a row is in the user's file: the file, its data row (1-based) and its name
/// in messages (see [`ExperimentRows::row_name`]).
#[derive(Debug, PartialEq)]
pub struct RowAt<'a> {
    /// The file.
    pub file: &'a str,
    /// Its data row, 1-based.
    pub row: u64,
    /// `row N`, or `resampled row N (time T s)` where the rows are not the file's.
    pub name: String,
}

/// The file and row of row `row` (0-based) of the experiments' rows taken one after
/// the other, as `pooled` joins them.
pub fn locate(exps: &[ExperimentRows], row: usize) -> Option<RowAt<'_>> {
    let mut left = row;
    for e in exps {
        if left < e.reference.len() {
            return locate_in(e, left);
        }
        left -= e.reference.len();
    }
    None
}

/// The file and row of row `row` (0-based) of one experiment.
pub fn locate_in(e: &ExperimentRows, row: usize) -> Option<RowAt<'_>> {
    Some(RowAt { file: e.file.as_str(), row: e.file_rows.get(row).copied()?, name: e.row_name(row, "row")? })
}

/// `err` from a fit of the pooled rows of `exps`, its row (if any) given as file and
/// data row; `doing` says which fit.
pub fn pooled_error(exps: &[ExperimentRows], cols: &Columns, doing: &str, err: CalibrationError) -> anyhow::Error {
    at_file_row(|row| locate(exps, row), cols, doing, err)
}

/// `err` from a fit of one experiment's rows, its row (if any) given as file and data
/// row; `doing` says which fit.
pub fn experiment_error(e: &ExperimentRows, cols: &Columns, doing: &str, err: CalibrationError) -> anyhow::Error {
    at_file_row(|row| locate_in(e, row), cols, doing, err)
}

fn at_file_row<'a>(
    locate: impl Fn(usize) -> Option<RowAt<'a>>,
    cols: &Columns,
    doing: &str,
    err: CalibrationError,
) -> anyhow::Error {
    match err {
        CalibrationError::SpeedOutsideTable { row, speed_rad_s, min_rad_s, max_rad_s } => match locate(row) {
            Some(RowAt { file, name, .. }) => anyhow!(
                "{file}: {name}, {}: speed {speed_rad_s} rad/s is outside the calibrated range \
                 [{min_rad_s}, {max_rad_s}] rad/s of --speed-edges and --extrapolation is `reject`",
                cols.describe("speed_rad_s")
            ),
            None => anyhow!(CalibrationError::SpeedOutsideTable { row, speed_rad_s, min_rad_s, max_rad_s })
                .context(doing.to_string()),
        },
        CalibrationError::NonFiniteRow { what, row, column } => match locate(row) {
            Some(RowAt { file, name, .. }) => {
                anyhow!("{file}: {name}: {doing}: {} is not finite", cols.describe(column))
            }
            None => anyhow!(CalibrationError::NonFiniteRow { what, row, column }).context(doing.to_string()),
        },
        CalibrationError::AtRow { what, row, why } => match locate(row) {
            Some(RowAt { file, name, .. }) => anyhow!("{file}: {name}: {doing}: {why}"),
            None => anyhow!(CalibrationError::AtRow { what, row, why }).context(doing.to_string()),
        },
        other => anyhow!(other).context(doing.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exp(file: &str, file_rows: &[u64]) -> ExperimentRows {
        ExperimentRows {
            label: file.into(),
            reference: vec![0.0; file_rows.len()],
            file: file.into(),
            file_rows: file_rows.to_vec(),
            ..Default::default()
        }
    }

    #[test]
    fn pooled_rows_map_to_their_file_and_row() {
        // a.csv kept rows 2, 3, 7 (after --held); b.csv rows 1, 2.
        let exps = [exp("a.csv", &[2, 3, 7]), exp("b.csv", &[1, 2])];
        let at = |k| locate(&exps, k).map(|r| (r.file, r.row, r.name));
        assert_eq!(at(0), Some(("a.csv", 2, "row 2".to_string())));
        assert_eq!(at(2), Some(("a.csv", 7, "row 7".to_string())));
        assert_eq!(at(3), Some(("b.csv", 1, "row 1".to_string())));
        assert_eq!(at(4), Some(("b.csv", 2, "row 2".to_string())));
        assert_eq!(at(5), None);
    }

    #[test]
    fn a_row_error_names_the_file_row_and_the_users_column() {
        let exps = [exp("a.csv", &[1, 2]), exp("b.csv", &[1, 2, 3])];
        let cols = Columns { reference: "torque", sensor: "volts", speed: Some("omega") };
        let err = CalibrationError::SpeedOutsideTable { row: 4, speed_rad_s: 9.0, min_rad_s: 2.0, max_rad_s: 8.0 };
        let e = pooled_error(&exps, &cols, "fitting", err).to_string();
        assert!(e.starts_with("b.csv: row 3, column `omega`: speed 9 rad/s is outside"), "{e}");
        let err = CalibrationError::NonFiniteRow { what: "metrics".into(), row: 1, column: "calibrated_nm" };
        let e = pooled_error(&exps, &cols, "fitting the static model", err).to_string();
        assert_eq!(e, "a.csv: row 2: fitting the static model: the calibrated torque (column `volts` through the fit) is not finite");
        // A row the experiments do not hold keeps the library's words, with the context.
        let err = CalibrationError::AtRow { what: "x".into(), row: 9, why: "bad".into() };
        let e = format!("{:#}", pooled_error(&exps, &cols, "fitting", err));
        assert_eq!(e, "fitting: x: row 10: bad");
    }
}
