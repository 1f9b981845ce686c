//! A table's time column read in seconds whatever time unit the file gives it: a text
//! header's `Time [ms]` or a Parquet field's `unit` metadata `ms` alike.

/// A time unit as `(mul, div)`: a time `t` in it is `t · mul / div` seconds (each step
/// exact or correctly rounded). `None`: not a time unit.
pub(crate) fn seconds_per(unit: &str) -> Option<(f64, f64)> {
    Some(match unit {
        "s" | "sec" => (1.0, 1.0),
        "ms" => (1.0, 1e3),
        "us" | "µs" | "μs" => (1.0, 1e6),
        "ns" => (1.0, 1e9),
        "min" => (60.0, 1.0),
        "h" => (3600.0, 1.0),
        _ => return None,
    })
}

use crate::error::IoError;

/// Which column is the time, and how it becomes seconds; the column's unit reads `s`
/// while it is converted.
#[derive(Debug, Clone, Default)]
pub(crate) struct TimeInSeconds {
    /// The column, `(mul, div)`, its unit as the file gave it, and its name.
    converted: Option<(usize, f64, f64, Option<String>, String)>,
}

impl TimeInSeconds {
    /// The column named `time`, converted if its unit is a time unit other than seconds.
    pub(crate) fn new(columns: &[String], units: &mut [Option<String>]) -> Self {
        let mut time = Self::default();
        time.set_column(columns, units, "time");
        time
    }

    /// Makes column `name` the time column; no such column: nothing changes.
    pub(crate) fn set_column(&mut self, columns: &[String], units: &mut [Option<String>], name: &str) {
        let Some(i) = columns.iter().position(|c| c == name) else { return };
        self.keep_as_written(units);
        let Some((mul, div)) = units[i].as_deref().and_then(seconds_per) else { return };
        let written = units[i].replace("s".to_string());
        self.converted = Some((i, mul, div, written, name.to_string())).filter(|_| (mul, div) != (1.0, 1.0));
    }

    /// Reads the time column as the file gives it (a config's scale converts it instead).
    pub(crate) fn keep_as_written(&mut self, units: &mut [Option<String>]) {
        if let Some((i, _, _, written, _)) = self.converted.take() {
            units[i] = written;
        }
    }

    /// The row's time in seconds; `row` is data row `row_number` of `path`. A finite time
    /// that seconds make infinite (`1e306` h) is an error naming the row and column.
    #[inline]
    pub(crate) fn apply(&self, row: &mut [f64], path: &std::path::Path, row_number: u64) -> Result<(), IoError> {
        let Some((i, mul, div, unit, name)) = &self.converted else { return Ok(()) };
        let (t, seconds) = (row[*i], row[*i] * mul / div);
        if t.is_finite() && !seconds.is_finite() {
            let unit = unit.as_deref().unwrap_or("");
            let msg = format!("row {row_number}, column `{name}`: {t:?} {unit} is beyond the seconds a number holds");
            return Err(IoError::Csv { path: path.to_path_buf(), msg });
        }
        row[*i] = seconds;
        Ok(())
    }
}
