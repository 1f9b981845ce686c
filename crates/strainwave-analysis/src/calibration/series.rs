//! From the readings of a recording to the loading series of [`din51309_figures`]:
//! steps from runs of equal reference torque, series cut at the zero readings, series
//! grouped by their torque steps, and the indication's quantization step.
//!
//! [`din51309_figures`]: super::din51309_figures

use super::din::{parse_series, same_torque};
use super::{check_columns, invalid, CalibrationError, LoadSeries, SeriesStep};

/// Loading series from the readings of one recording (or one experiment of it).
///
/// A **step** is a run of consecutive rows with the same reference torque (the nominal
/// torque a dead-weight rig logs, compared exactly; `−0` equals `0`) and mounting
/// position; its indication is the mean of the run's readings:
///
/// ```text
/// step k: M_k = torque of the run,  i_k = (1/n_k) Σ_{rows of the run} indication
/// ```
///
/// Series are cut at the zero-torque steps: a series runs from a zero step through the
/// loaded steps to the next zero step, which is its final zero reading and also the
/// next series' initial zero (a remount at zero torque gives two zero steps: the first
/// closes one series, the second opens the next). Loading and unloading follow from the torque sequence, so
/// no direction column is needed. A series' mounting position is `mounting_deg` at its
/// first row (0 without the column); it must not change inside a series.
///
/// Errors: columns of different lengths, a non-finite row (named), a recording that
/// does not start with a zero reading, no loaded step, a mounting change inside a series.
///
/// ```
/// use strainwave_analysis::calibration::split_load_series;
/// // Two readings per step: 0, 10, 20, 10, 0 N·m, then −10, 0 N·m.
/// let t = [0.0, 0.0, 10.0, 10.0, 20.0, 20.0, 10.0, 10.0, 0.0, 0.0, -10.0, -10.0, 0.0, 0.0];
/// let v = [0.0, 0.2, 1.0, 1.2, 2.0, 2.0, 1.1, 1.1, 0.1, 0.1, -1.0, -1.0, 0.0, 0.0];
/// let s = split_load_series(&t, &v, None).unwrap();
/// assert_eq!(s.len(), 2);
/// assert_eq!(s[0].steps.len(), 5);
/// assert!((s[0].steps[1].indication - 1.1).abs() < 1e-12);
/// assert_eq!(s[1].steps[0].indication, 0.1); // shared zero reading
/// ```
pub fn split_load_series(
    torque_nm: &[f64],
    indication: &[f64],
    mounting_deg: Option<&[f64]>,
) -> Result<Vec<LoadSeries>, CalibrationError> {
    let what = "loading series";
    let mut cols: Vec<(&'static str, &[f64])> = vec![("torque_nm", torque_nm), ("indication", indication)];
    if let Some(m) = mounting_deg {
        cols.push(("mounting_deg", m));
    }
    let n = check_columns(what, &cols)?;
    // Steps: (first row, torque, mean indication).
    let position = |row: usize| mounting_deg.map_or(0.0, |m| m[row]);
    let mut steps: Vec<(usize, SeriesStep)> = Vec::new();
    let mut start = 0;
    while start < n {
        let (m, p) = (torque_nm[start], position(start));
        let end = (start..n).find(|&i| torque_nm[i] != m || position(i) != p).unwrap_or(n);
        let mean = indication[start..end].iter().sum::<f64>() / (end - start) as f64;
        steps.push((start, SeriesStep { torque_nm: if m == 0.0 { 0.0 } else { m }, indication: mean }));
        start = end;
    }
    match steps.first() {
        None => return Err(CalibrationError::TooFewRows { what: what.into(), needed: 2, got: 0 }),
        Some((_, s)) if s.torque_nm != 0.0 => {
            return Err(CalibrationError::AtRow {
                what: what.into(),
                row: 0,
                why: format!("the first reading is at {} N·m; a series starts with a zero-torque reading", s.torque_nm),
            })
        }
        _ => {}
    }
    let mut out = Vec::new();
    let mut current: Vec<(usize, SeriesStep)> = Vec::new();
    let close = |cur: &[(usize, SeriesStep)], out: &mut Vec<LoadSeries>| -> Result<(), CalibrationError> {
        if cur.len() < 2 {
            return Ok(());
        }
        let mounting = position(cur[0].0);
        if let Some(&(row, _)) = cur.iter().find(|(row, _)| position(*row) != mounting) {
            return Err(CalibrationError::AtRow {
                what: what.into(),
                row,
                why: format!(
                    "the mounting position changes from {mounting}° to {}° inside a series; \
                     return to zero torque before remounting",
                    position(row)
                ),
            });
        }
        out.push(LoadSeries { mounting_deg: mounting, steps: cur.iter().map(|s| s.1).collect() });
        Ok(())
    };
    for &(row, st) in &steps {
        if st.torque_nm == 0.0 {
            current.push((row, st));
            close(&current, &mut out)?;
            current = vec![(row, st)];
        } else {
            current.push((row, st));
        }
    }
    close(&current, &mut out)?;
    if out.is_empty() {
        return Err(invalid(what, "no loaded step: every reading is at zero torque"));
    }
    Ok(out)
}

/// Groups series that share their loading steps (the same increasing torques), as
/// [`din51309_figures`](super::din51309_figures) needs: indices into `series`, groups
/// in order of first appearance (e.g. low range / full range, positive / negative torque).
///
/// ```
/// use strainwave_analysis::calibration::{group_by_levels, LoadSeries};
/// let s = [
///     LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, 1.0), (0.0, 0.0)]),
///     LoadSeries::new(0.0, &[(0.0, 0.0), (-10.0, -1.0), (0.0, 0.0)]),
///     LoadSeries::new(90.0, &[(0.0, 0.0), (10.0, 1.1), (0.0, 0.0)]),
/// ];
/// assert_eq!(group_by_levels(&s).unwrap(), vec![vec![0, 2], vec![1]]);
/// ```
pub fn group_by_levels(series: &[LoadSeries]) -> Result<Vec<Vec<usize>>, CalibrationError> {
    let mut keys: Vec<Vec<f64>> = Vec::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, s) in series.iter().enumerate() {
        let levels: Vec<f64> = parse_series(i, s)?.loading.iter().map(|l| l.0).collect();
        let same = |k: &Vec<f64>| k.len() == levels.len() && k.iter().zip(&levels).all(|(a, b)| same_torque(*a, *b));
        match keys.iter().position(same) {
            Some(g) => groups[g].push(i),
            None => {
                keys.push(levels);
                groups.push(vec![i]);
            }
        }
    }
    Ok(groups)
}

/// The quantization step of an indication: the smallest gap between distinct finite
/// values (gaps below `1e-9 · max |value|` count as rounding, not as distinct values).
/// `None` with fewer than two distinct values. With enough noisy readings of an ADC
/// this is its LSB: the resolution `a` of DIN 51309.
///
/// ```
/// use strainwave_analysis::calibration::quantization_step;
/// let lsb = 10.0 / 32768.0;
/// let v: Vec<f64> = [3, 5, 4, 9, 3].iter().map(|&k| k as f64 * lsb).collect();
/// assert!((quantization_step(&v).unwrap() - lsb).abs() < 1e-15);
/// ```
pub fn quantization_step(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let scale = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let floor = 1e-9 * scale;
    v.windows(2).map(|w| w[1] - w[0]).filter(|&d| d > floor).min_by(f64::total_cmp)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{din51309_figures, DinOptions};

    const TIGHT: f64 = 1e-12;

    /// The locked-wave-generator order: up and down at positive torque, then at negative
    /// torque, three readings per step, zero readings shared between the two series.
    fn readings(mounting: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let torques = [0.0, 5.0, 10.0, 5.0, 0.0, -0.0, -5.0, -10.0, -5.0, -0.0];
        let gains = [0.0, 0.50, 1.00, 0.52, 0.01, 0.01, -0.49, -1.00, -0.51, 0.0];
        let (mut t, mut v, mut m) = (vec![], vec![], vec![]);
        for (tq, g) in torques.iter().zip(gains) {
            for k in [-1.0, 0.0, 1.0] {
                t.push(*tq);
                v.push(g + 0.001 * k);
                m.push(mounting);
            }
        }
        (t, v, m)
    }

    #[test]
    fn locked_wave_generator_order_gives_two_series() {
        let (t, v, m) = readings(45.0);
        let s = split_load_series(&t, &v, Some(&m)).unwrap();
        assert_eq!(s.len(), 2);
        assert!(s.iter().all(|x| x.mounting_deg == 45.0));
        let torques: Vec<f64> = s[0].steps.iter().map(|x| x.torque_nm).collect();
        assert_eq!(torques, vec![0.0, 5.0, 10.0, 5.0, 0.0]);
        // The zero after positive unloading (0.01) and before negative loading (0.01) is one run of six readings.
        assert!((s[0].steps[4].indication - 0.01).abs() < TIGHT && (s[1].steps[0].indication - 0.01).abs() < TIGHT);
        assert!((s[1].steps[2].indication + 1.0).abs() < TIGHT);
        // Positive and negative series have different steps: two groups.
        assert_eq!(group_by_levels(&s).unwrap(), vec![vec![0], vec![1]]);
        // Reversibility at 5 N·m: |0.52 − 0.50| / 0.50; zero error (0.01 − 0) / 1.00.
        let r = din51309_figures(&s[..1], &DinOptions::default()).unwrap();
        assert!((r.steps[0].reversibility.unwrap() - 0.04).abs() < 1e-9);
        assert!((r.max_zero_error.unwrap() - 0.01).abs() < 1e-9);
    }

    #[test]
    fn bad_readings_are_named() {
        let (t, mut v, mut m) = readings(0.0);
        let err = split_load_series(&t[3..], &v[3..], None).unwrap_err();
        assert!(matches!(err, CalibrationError::AtRow { row: 0, .. }), "{err:?}");
        assert!(err.to_string().starts_with("loading series: row 1: the first reading is at 5 N·m"), "{err}");
        m[7] = 90.0;
        let err = split_load_series(&t, &v, Some(&m)).unwrap_err();
        assert!(matches!(err, CalibrationError::AtRow { row: 7, .. }), "{err:?}");
        assert!(err.to_string().contains("row 8: the mounting position changes from 0° to 90°"), "{err}");
        v[4] = f64::NAN;
        assert_eq!(
            split_load_series(&t, &v, None).unwrap_err(),
            CalibrationError::NonFiniteRow { what: "loading series".into(), row: 4, column: "indication" }
        );
        assert!(split_load_series(&[0.0, 0.0], &[0.0, 0.1], None).is_err());
        assert!(matches!(split_load_series(&[], &[], None), Err(CalibrationError::TooFewRows { .. })));
    }

    #[test]
    fn quantization_step_ignores_rounding_gaps() {
        let lsb = 1.0 / 4096.0;
        let mut v: Vec<f64> = (0..50).map(|k| ((k * 7) % 13) as f64 * lsb + 0.3).collect();
        v.push(v[0] * (1.0 + 1e-15));
        assert!((quantization_step(&v).unwrap() - lsb).abs() < 1e-12);
        assert_eq!(quantization_step(&[1.0, 1.0, f64::NAN]), None);
    }
}
