//! Speed-dependent models `T_ref = α(ω) x + β(ω)`: a polynomial in speed or a lookup
//! table of affine fits per speed bin (the embedded-sensor article dynamic model).

use serde::{Deserialize, Serialize};
use strainwave_core::calibration::{Calibration, Extrapolation as CoreExtrapolation};

use super::metrics::placeholder_metrics;
use super::{
    check_columns, error_metrics, fit_affine, invalid, require_two_values, CalibrationError, CalibrationFile,
    Coefficients, ErrorMetrics, ModelKind, MAX_TABLE_LEN,
};
use crate::lstsq::{self, expansion_matrix};

/// Extrapolation policy outside a speed table or fitted speed range (file key
/// `extrapolation = "clamp" | "linear" | "reject"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Extrapolation {
    /// Hold the end coefficients.
    Clamp,
    /// Continue the end slope.
    Linear,
    /// Refuse the sample.
    Reject,
}

impl std::str::FromStr for Extrapolation {
    type Err = String;

    /// `clamp`, `linear` or `reject`; the error lists them.
    fn from_str(name: &str) -> Result<Self, String> {
        let table = [("clamp", Self::Clamp), ("linear", Self::Linear), ("reject", Self::Reject)];
        crate::choice::parse(name, &table, 3)
    }
}

impl From<Extrapolation> for CoreExtrapolation {
    fn from(e: Extrapolation) -> Self {
        match e {
            Extrapolation::Clamp => CoreExtrapolation::Clamp,
            Extrapolation::Linear => CoreExtrapolation::Linear,
            Extrapolation::Reject => CoreExtrapolation::Reject,
        }
    }
}

/// How rows are grouped into speed bins for a table.
#[derive(Debug, Clone, PartialEq)]
pub enum SpeedBins {
    /// Bin edges in rad/s, strictly increasing: bins `[e_0, e_1)`, …, `[e_{k−1}, e_k]`.
    /// Rows outside `[e_0, e_k]` are left out of the bin fits (counted in
    /// [`SpeedFit::rows_unbinned`]).
    Edges(Vec<f64>),
    /// `n` bins of equal width between the smallest and largest speed.
    EqualWidth(usize),
}

/// The speed dependence of `α(ω)`, `β(ω)`.
#[derive(Debug, Clone, PartialEq)]
pub enum SpeedDependence {
    /// `α`, `β` polynomials of this degree in speed, fitted jointly:
    /// `T_ref = Σ_k a_k ω^k · x + Σ_k b_k ω^k` (one least-squares problem, speed centred
    /// and scaled internally, coefficients returned in rad/s, lowest order first).
    Polynomial {
        /// Degree (0 = speed-independent).
        degree: usize,
    },
    /// A table: an affine fit per speed bin, breakpoint at the bin's mean speed;
    /// empty bins are skipped (and listed).
    Table(SpeedBins),
}

/// The affine fit of one speed bin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedBinFit {
    /// Bin start, rad/s.
    pub lo_rad_s: f64,
    /// Bin end, rad/s.
    pub hi_rad_s: f64,
    /// Rows in the bin.
    pub rows: usize,
    /// Mean speed of the rows: the table breakpoint, rad/s.
    pub mean_speed_rad_s: f64,
    /// α of the bin.
    pub alpha: f64,
    /// β of the bin, N·m.
    pub beta_nm: f64,
}

/// A speed-dependent calibration fit.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedFit {
    /// [`ModelKind::SpeedTable`] or [`ModelKind::SpeedPoly`].
    pub model: ModelKind,
    /// Table breakpoints, rad/s (empty for a polynomial).
    pub speed_rad_s: Vec<f64>,
    /// Range without extrapolation: table ends, or the data's speed range for a polynomial.
    pub speed_range_rad_s: (f64, f64),
    /// α table values or polynomial coefficients (lowest order first).
    pub alpha: Vec<f64>,
    /// β table values or polynomial coefficients, N·m.
    pub beta_nm: Vec<f64>,
    /// Policy outside the range.
    pub extrapolation: Extrapolation,
    /// Per-bin fits (table only).
    pub bins: Vec<SpeedBinFit>,
    /// Bins without rows, `(lo, hi)` rad/s, skipped.
    pub empty_bins: Vec<(f64, f64)>,
    /// Rows outside the given bin edges, not used by any bin fit.
    pub rows_unbinned: usize,
    /// Rows whose speed lies outside the range (evaluated by the policy).
    pub rows_extrapolated: usize,
    /// Rows the `reject` policy refused; left out of `metrics`.
    pub rows_rejected: usize,
    /// Metrics of the calibration as the controller applies it (interpolated table or
    /// polynomial, with the policy) over all rows not rejected.
    pub metrics: ErrorMetrics,
}

impl SpeedFit {
    /// The calibration file (`speed-table` or `speed-poly`).
    pub fn to_file(&self) -> CalibrationFile {
        let poly = self.model == ModelKind::SpeedPoly;
        CalibrationFile {
            model: self.model,
            description: None,
            gain_nm_per_v: None,
            alpha: Some(Coefficients::List(self.alpha.clone())),
            beta_nm: Some(Coefficients::List(self.beta_nm.clone())),
            speed_rad_s: (!poly).then(|| self.speed_rad_s.clone()),
            speed_range_rad_s: poly.then(|| vec![self.speed_range_rad_s.0, self.speed_range_rad_s.1]),
            extrapolation: Some(self.extrapolation),
            metrics: Some(self.metrics),
        }
    }

    /// The core calibration (`K` ≥ the table length or coefficient count).
    pub fn to_core<const K: usize>(&self) -> Result<Calibration<f64, K>, CalibrationError> {
        self.to_file().to_core::<f64, K>()
    }
}

/// Fits `T_ref = α(ω) · sensor + β(ω)` (the embedded-sensor article dynamic model).
///
/// Errors: non-finite rows (named), all rows at one speed or one load (singular), a bin
/// whose rows are all at one load (named bin), fewer than two non-empty bins, more than
/// [`MAX_TABLE_LEN`] breakpoints or coefficients, and under [`Extrapolation::Reject`] a
/// row outside given bin edges ([`CalibrationError::SpeedOutsideTable`], row named).
/// Under `Clamp` or `Linear` such rows are counted in [`SpeedFit::rows_unbinned`],
/// left out of the bin fits and evaluated by the policy in the metrics.
///
/// ```
/// use strainwave_analysis::calibration::{fit_speed_dependent, Extrapolation, SpeedBins, SpeedDependence};
/// // α = 1.5 + 0.01 ω, β = −0.09, sampled at two loads per speed.
/// let (mut x, mut t, mut w) = (vec![], vec![], vec![]);
/// for &speed in &[0.0, 2.0, 4.0, 6.0] {
///     for &load in &[1.0, 8.0] {
///         x.push(load);
///         w.push(speed);
///         t.push((1.5 + 0.01 * speed) * load - 0.09);
///     }
/// }
/// let dep = SpeedDependence::Polynomial { degree: 1 };
/// let f = fit_speed_dependent(&x, &t, &w, &dep, Extrapolation::Clamp, None).unwrap();
/// assert!((f.alpha[1] - 0.01).abs() < 1e-12 && (f.beta_nm[0] + 0.09).abs() < 1e-12);
/// let tab = SpeedDependence::Table(SpeedBins::EqualWidth(4));
/// let g = fit_speed_dependent(&x, &t, &w, &tab, Extrapolation::Linear, None).unwrap();
/// assert_eq!(g.speed_rad_s, vec![0.0, 2.0, 4.0, 6.0]);
/// ```
pub fn fit_speed_dependent(
    sensor: &[f64],
    reference_nm: &[f64],
    speed_rad_s: &[f64],
    dependence: &SpeedDependence,
    extrapolation: Extrapolation,
    full_scale_nm: Option<f64>,
) -> Result<SpeedFit, CalibrationError> {
    let what = "speed-dependent fit";
    let n = check_columns(what, &[("sensor", sensor), ("reference_nm", reference_nm), ("speed_rad_s", speed_rad_s)])?;
    if n == 0 {
        return Err(CalibrationError::TooFewRows { what: what.into(), needed: 2, got: 0 });
    }
    if let (SpeedDependence::Table(SpeedBins::Edges(e)), Extrapolation::Reject) = (dependence, extrapolation) {
        // Data outside the table the user asked for would be neither fitted nor evaluable.
        if let (Some(&min_rad_s), Some(&max_rad_s)) = (e.first(), e.last()) {
            let outside = speed_rad_s.iter().position(|&w| w < min_rad_s || w > max_rad_s);
            if let Some(row) = outside {
                return Err(CalibrationError::SpeedOutsideTable {
                    row,
                    speed_rad_s: speed_rad_s[row],
                    min_rad_s,
                    max_rad_s,
                });
            }
        }
    }
    let mut fit = match dependence {
        SpeedDependence::Polynomial { degree } => fit_speed_poly(sensor, reference_nm, speed_rad_s, *degree)?,
        SpeedDependence::Table(bins) => fit_speed_table(sensor, reference_nm, speed_rad_s, bins)?,
    };
    fit.extrapolation = extrapolation;
    let core = fit.to_core::<MAX_TABLE_LEN>()?;
    let (lo, hi) = fit.speed_range_rad_s;
    let (mut cal, mut refs) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let w = speed_rad_s[i];
        if w < lo || w > hi {
            fit.rows_extrapolated += 1;
        }
        match core.apply(sensor[i], w) {
            Ok(v) => {
                cal.push(v);
                refs.push(reference_nm[i]);
            }
            Err(strainwave_core::Error::OutOfRange("speed_rad_s")) => fit.rows_rejected += 1,
            Err(e) => return Err(e.into()),
        }
    }
    if cal.is_empty() {
        return Err(invalid(what, "every row was rejected by `extrapolation = reject`"));
    }
    fit.metrics = error_metrics(&cal, &refs, full_scale_nm)?;
    Ok(fit)
}

fn fit_speed_poly(x: &[f64], t: &[f64], w: &[f64], degree: usize) -> Result<SpeedFit, CalibrationError> {
    let what = "speed polynomial fit";
    if degree >= MAX_TABLE_LEN {
        return Err(invalid(what, format!("degree {degree} exceeds {}", MAX_TABLE_LEN - 1)));
    }
    let k = degree + 1;
    let lo = w.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    // Even at degree 0 a speed model needs data at two speeds (its range must be an interval).
    require_two_values(what, "speed_rad_s", w)?;
    require_two_values(what, "sensor", x)?;
    let center = 0.5 * lo + 0.5 * hi;
    let scale = 0.5 * hi - 0.5 * lo;
    let m = x.len();
    let mut a = Vec::with_capacity(m * 2 * k);
    for i in 0..m {
        let u = (w[i] - center) / scale;
        let powers: Vec<f64> = (0..k).scan(1.0, |p, _| Some(std::mem::replace(p, *p * u))).collect();
        a.extend(powers.iter().map(|p| p * x[i]));
        a.extend(powers.iter().copied());
    }
    let sol = lstsq::lstsq(&a, 2 * k, t)?;
    let tm = expansion_matrix(center, scale, k);
    let expand = |p: &[f64]| -> Vec<f64> { (0..k).map(|j| (0..k).map(|q| tm[j * k + q] * p[q]).sum()).collect() };
    Ok(SpeedFit {
        model: ModelKind::SpeedPoly,
        speed_rad_s: Vec::new(),
        speed_range_rad_s: (lo, hi),
        alpha: expand(&sol.x[..k]),
        beta_nm: expand(&sol.x[k..]),
        extrapolation: Extrapolation::Clamp,
        bins: Vec::new(),
        empty_bins: Vec::new(),
        rows_unbinned: 0,
        rows_extrapolated: 0,
        rows_rejected: 0,
        metrics: placeholder_metrics(),
    })
}

fn fit_speed_table(x: &[f64], t: &[f64], w: &[f64], bins: &SpeedBins) -> Result<SpeedFit, CalibrationError> {
    let what = "speed table fit";
    let edges = match bins {
        SpeedBins::Edges(e) => {
            if e.len() < 3 {
                return Err(invalid("speed bin edges", "a table needs at least two bins (three edges)"));
            }
            if e.len() > MAX_TABLE_LEN {
                return Err(invalid("speed bin edges", format!("at most {MAX_TABLE_LEN} edges, got {}", e.len())));
            }
            for (i, v) in e.iter().enumerate() {
                if !v.is_finite() {
                    return Err(CalibrationError::NonFiniteRow {
                        what: "speed bin edges".into(),
                        row: i,
                        column: "edge",
                    });
                }
                if i > 0 && *v <= e[i - 1] {
                    return Err(invalid("speed bin edges", format!("edge {i} ({v}) is not above edge {}", i - 1)));
                }
            }
            e.clone()
        }
        SpeedBins::EqualWidth(nb) => {
            if *nb < 2 {
                return Err(invalid("speed bins", "a table needs at least two bins"));
            }
            if *nb >= MAX_TABLE_LEN {
                return Err(invalid("speed bins", format!("at most {} bins, got {nb}", MAX_TABLE_LEN - 1)));
            }
            require_two_values(what, "speed_rad_s", w)?;
            let lo = w.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (0..=*nb).map(|i| if i == *nb { hi } else { lo + (hi - lo) * i as f64 / *nb as f64 }).collect()
        }
    };
    let nb = edges.len() - 1;
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); nb];
    let mut unbinned = 0;
    for (i, &wi) in w.iter().enumerate() {
        if wi < edges[0] || wi > edges[nb] {
            unbinned += 1;
            continue;
        }
        // Bin b holds [e_b, e_{b+1}); the last bin is closed.
        let b = edges.partition_point(|&e| e <= wi).saturating_sub(1).min(nb - 1);
        members[b].push(i);
    }
    let mut fits = Vec::new();
    let mut empty = Vec::new();
    for (b, idx) in members.iter().enumerate() {
        let (lo, hi) = (edges[b], edges[b + 1]);
        if idx.is_empty() {
            empty.push((lo, hi));
            continue;
        }
        let bx: Vec<f64> = idx.iter().map(|&i| x[i]).collect();
        let bt: Vec<f64> = idx.iter().map(|&i| t[i]).collect();
        let f = fit_affine(&bx, &bt, None).map_err(|e| CalibrationError::Bin {
            index: b,
            lo_rad_s: lo,
            hi_rad_s: hi,
            source: Box::new(e),
        })?;
        let mean_speed = idx.iter().map(|&i| w[i]).sum::<f64>() / idx.len() as f64;
        fits.push(SpeedBinFit {
            lo_rad_s: lo,
            hi_rad_s: hi,
            rows: idx.len(),
            mean_speed_rad_s: mean_speed,
            alpha: f.alpha,
            beta_nm: f.beta_nm,
        });
    }
    if fits.len() < 2 {
        return Err(invalid(what, format!("{} non-empty bin(s); a table needs at least two", fits.len())));
    }
    if fits.len() > MAX_TABLE_LEN {
        return Err(invalid(what, format!("{} bins exceed the table limit {MAX_TABLE_LEN}", fits.len())));
    }
    let speed: Vec<f64> = fits.iter().map(|f| f.mean_speed_rad_s).collect();
    Ok(SpeedFit {
        model: ModelKind::SpeedTable,
        speed_range_rad_s: (speed[0], speed[speed.len() - 1]),
        speed_rad_s: speed,
        alpha: fits.iter().map(|f| f.alpha).collect(),
        beta_nm: fits.iter().map(|f| f.beta_nm).collect(),
        extrapolation: Extrapolation::Clamp,
        bins: fits,
        empty_bins: empty,
        rows_unbinned: unbinned,
        rows_extrapolated: 0,
        rows_rejected: 0,
        metrics: placeholder_metrics(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TIGHT: f64 = 1e-12;

    fn speed_data() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        // α = 1.5 + 0.02 ω, β = −0.1 + 0.005 ω at speeds 1..=5 rad/s, loads 0..10.
        let (mut x, mut t, mut w) = (vec![], vec![], vec![]);
        for s in 1..=5 {
            for l in 0..=10 {
                let (ws, xl) = (s as f64, l as f64);
                x.push(xl);
                w.push(ws);
                t.push((1.5 + 0.02 * ws) * xl - 0.1 + 0.005 * ws);
            }
        }
        (x, t, w)
    }

    #[test]
    fn speed_table_exact_and_extrapolation_reported() {
        let (x, t, w) = speed_data();
        let dep = SpeedDependence::Table(SpeedBins::Edges(vec![0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5]));
        let f = fit_speed_dependent(&x, &t, &w, &dep, Extrapolation::Reject, Some(20.0)).unwrap();
        assert_eq!(f.speed_rad_s, vec![1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(f.empty_bins, vec![(5.5, 6.5)]);
        // Edges that leave rows out: an error under reject, counted under clamp.
        let narrow = SpeedDependence::Table(SpeedBins::Edges(vec![1.5, 3.5, 5.5]));
        let err = fit_speed_dependent(&x, &t, &w, &narrow, Extrapolation::Reject, None).unwrap_err();
        assert!(matches!(err, CalibrationError::SpeedOutsideTable { row: 0, .. }), "{err}");
        let g = fit_speed_dependent(&x, &t, &w, &narrow, Extrapolation::Clamp, None).unwrap();
        assert_eq!(g.rows_unbinned, 11);
        assert!(f.metrics.max_abs_error_nm < 1e-12 && f.rows_rejected == 0);
        for (i, a) in f.alpha.iter().enumerate() {
            assert!((a - (1.5 + 0.02 * (i + 1) as f64)).abs() < TIGHT);
        }
        let file = f.to_file();
        let text = file.to_toml_string().unwrap();
        assert!(text.contains("extrapolation = \"reject\""), "{text}");
        let back = CalibrationFile::from_toml_str(&text).unwrap();
        assert_eq!(back, file);
        // Applying at 6 rad/s is refused and names the row.
        let err = back.apply(&[1.0, 2.0], Some(&[3.0, 6.0])).unwrap_err();
        assert!(matches!(err, CalibrationError::SpeedOutsideTable { row: 1, .. }), "{err}");
        // With clamp, the row is flagged instead.
        let mut clamp = back.clone();
        clamp.extrapolation = Some(Extrapolation::Clamp);
        let ev = clamp.apply(&[1.0, 2.0], Some(&[3.0, 6.0])).unwrap();
        assert_eq!(ev.extrapolated_rows, vec![1]);
        assert!((ev.torque_nm[1] - (2.0 * 1.6 - 0.075)).abs() < TIGHT);
        assert!(matches!(back.apply(&[1.0], None), Err(CalibrationError::Invalid { .. })));
    }

    #[test]
    fn speed_poly_exact_and_bin_errors() {
        let (x, t, w) = speed_data();
        let dep = SpeedDependence::Polynomial { degree: 2 };
        let f = fit_speed_dependent(&x, &t, &w, &dep, Extrapolation::Linear, None).unwrap();
        assert!((f.alpha[0] - 1.5).abs() < 1e-10 && (f.alpha[1] - 0.02).abs() < 1e-10 && f.alpha[2].abs() < 1e-10);
        assert!((f.beta_nm[0] + 0.1).abs() < 1e-10 && (f.beta_nm[1] - 0.005).abs() < 1e-10);
        assert_eq!(f.speed_range_rad_s, (1.0, 5.0));
        let core = f.to_core::<3>().unwrap();
        assert!((core.apply(10.0, 3.0).unwrap() - (15.6 - 0.085)).abs() < 1e-9);
        // A bin whose rows are all at one load.
        let x2 = [1.0, 1.0, 1.0, 2.0];
        let t2 = [1.0, 1.1, 1.0, 2.0];
        let w2 = [0.0, 0.0, 1.0, 1.0];
        let dep = SpeedDependence::Table(SpeedBins::EqualWidth(2));
        let err = fit_speed_dependent(&x2, &t2, &w2, &dep, Extrapolation::Clamp, None).unwrap_err();
        assert!(matches!(err, CalibrationError::Bin { index: 0, .. }), "{err}");
        // All rows at one speed.
        let err = fit_speed_dependent(
            &x2,
            &t2,
            &[2.0; 4],
            &SpeedDependence::Polynomial { degree: 1 },
            Extrapolation::Clamp,
            None,
        )
        .unwrap_err();
        assert!(matches!(err, CalibrationError::SingleValue { column: "speed_rad_s", .. }));
        assert!(matches!(
            fit_speed_dependent(&x2, &t2, &[0.0, f64::NAN, 1.0, 1.0], &dep, Extrapolation::Clamp, None),
            Err(CalibrationError::NonFiniteRow { row: 1, column: "speed_rad_s", .. })
        ));
    }
}
