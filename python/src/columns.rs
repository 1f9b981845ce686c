//! A caller's column arrays as a row source, and rows gathered back into columns.

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use strainwave_io::IoError;
use strainwave_joint::run::{RowSink, RowSource};

/// Borrowed `float64` columns of equal length, read row by row.
pub struct ColumnSource<'a> {
    names: Vec<String>,
    data: Vec<&'a [f64]>,
    rows: usize,
    next: usize,
}

impl<'a> ColumnSource<'a> {
    /// Columns `data` named `names`; the caller has checked that the lengths agree.
    pub fn new(names: Vec<String>, data: Vec<&'a [f64]>) -> Self {
        let rows = data.first().map_or(0, |c| c.len());
        Self { names, data, rows, next: 0 }
    }
}

impl RowSource for ColumnSource<'_> {
    fn columns(&self) -> &[String] {
        &self.names
    }
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        row.clear();
        if self.next >= self.rows {
            return Ok(false);
        }
        let k = self.next;
        row.extend(self.data.iter().map(|c| c[k]));
        self.next += 1;
        Ok(true)
    }
    fn rows_read(&self) -> u64 {
        self.next as u64
    }
}

/// Rows written into the caller's columns, keeping only columns from `keep_from` on (the
/// ones a filter adds; the caller still has the others).
pub struct ColumnSink<'a> {
    keep_from: usize,
    data: &'a mut Vec<Vec<f64>>,
    rows: u64,
}

impl<'a> ColumnSink<'a> {
    /// A sink into `data` for `width` columns that keeps the columns `keep_from..width`,
    /// with room for `rows` rows.
    pub fn new(data: &'a mut Vec<Vec<f64>>, width: usize, keep_from: usize, rows: usize) -> Self {
        let kept = width.saturating_sub(keep_from);
        *data = (0..kept).map(|_| Vec::with_capacity(rows)).collect();
        Self { keep_from, data, rows: 0 }
    }
}

impl RowSink for ColumnSink<'_> {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        for (c, v) in self.data.iter_mut().zip(&row[self.keep_from.min(row.len())..]) {
            c.push(*v);
        }
        self.rows += 1;
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
    fn finish(self) -> Result<u64, IoError> {
        Ok(self.rows)
    }
}

/// Read-only views of the caller's arrays (copied only when not contiguous).
pub struct Arrays<'py> {
    views: Vec<PyReadonlyArray1<'py, f64>>,
    copies: Vec<Option<Vec<f64>>>,
}

impl<'py> Arrays<'py> {
    /// Borrows `arrays`, checking that there is one per name and that they have one length.
    pub fn new(names: &[String], arrays: Vec<PyReadonlyArray1<'py, f64>>) -> PyResult<Self> {
        if names.len() != arrays.len() {
            return Err(crate::error::StrainwaveError::new_err(format!(
                "{} column names for {} arrays",
                names.len(),
                arrays.len()
            )));
        }
        let n = arrays.first().map_or(0, |a| a.as_array().len());
        if let Some((name, a)) = names.iter().zip(&arrays).find(|(_, a)| a.as_array().len() != n) {
            return Err(crate::error::StrainwaveError::new_err(format!(
                "column `{name}` has {} rows, the first column {n}",
                a.as_array().len()
            )));
        }
        let copies = arrays
            .iter()
            .map(|a| if a.as_slice().is_ok() { None } else { Some(a.as_array().iter().copied().collect()) })
            .collect();
        Ok(Self { views: arrays, copies })
    }

    /// The columns as slices.
    pub fn slices(&self) -> Vec<&[f64]> {
        self.views
            .iter()
            .zip(&self.copies)
            .map(|(v, c)| match c {
                Some(c) => c.as_slice(),
                None => v.as_slice().unwrap_or(&[]),
            })
            .collect()
    }
}

/// Column names and their arrays, as Python receives a recording.
pub type Columns<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>);

/// Columns as numpy arrays (moved, not copied).
pub fn to_numpy(py: Python<'_>, columns: Vec<Vec<f64>>) -> Vec<Bound<'_, PyArray1<f64>>> {
    columns.into_iter().map(|c| PyArray1::from_vec(py, c)).collect()
}
