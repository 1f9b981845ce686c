//! DIN 51309 / EURAMET cg-14 figures from repeated loading series.

use super::{invalid, CalibrationError};
use crate::lstsq;

/// One step of a loading series: reference torque and the device's indication.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesStep {
    /// Reference (applied) torque, N·m.
    pub torque_nm: f64,
    /// Indication of the device (any unit: mV/V, V, N·m).
    pub indication: f64,
}

/// A loading (and optionally unloading) series in one mounting position.
///
/// Steps in the order measured: first the zero reading (torque 0), then increasing
/// torque to the top step, then optionally decreasing torque, optionally ending with
/// the zero reading after unloading (needed for the zero error).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSeries {
    /// Mounting position of the device about its axis, degrees (0, 120, 240 typical).
    pub mounting_deg: f64,
    /// The steps.
    pub steps: Vec<SeriesStep>,
}

impl LoadSeries {
    /// A series from `(torque_nm, indication)` pairs.
    ///
    /// ```
    /// use strainwave_analysis::calibration::LoadSeries;
    /// let s = LoadSeries::new(120.0, &[(0.0, 0.0), (10.0, 1.01), (20.0, 2.02), (10.0, 1.03), (0.0, 0.004)]);
    /// assert_eq!(s.steps.len(), 5);
    /// ```
    pub fn new(mounting_deg: f64, steps: &[(f64, f64)]) -> Self {
        Self {
            mounting_deg,
            steps: steps.iter().map(|&(torque_nm, indication)| SeriesStep { torque_nm, indication }).collect(),
        }
    }
}

/// Options of [`din51309_figures`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DinOptions {
    /// Degree of the interpolation curve, 1 to 3.
    pub interpolation_degree: usize,
    /// Fit the curve through the origin (no constant term): deflections are zero at
    /// zero torque by construction.
    pub through_zero: bool,
    /// Resolution of the indication (same unit), for the relative resolution `r`.
    pub resolution: Option<f64>,
}

impl Default for DinOptions {
    fn default() -> Self {
        Self { interpolation_degree: 1, through_zero: true, resolution: None }
    }
}

/// The figures at one torque step; relative figures are fractions (×100 for %).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DinStep {
    /// Step torque, N·m.
    pub torque_nm: f64,
    /// `X̄_wr`: mean increasing-torque deflection of the series in the first mounting position.
    pub mean_deflection_same_position: f64,
    /// `X̄_r`: mean increasing-torque deflection of the first series of each mounting position.
    pub mean_deflection: f64,
    /// `X_a`: the interpolation curve at this torque.
    pub fitted_deflection: f64,
    /// `b'`: relative repeatability (≥ 2 series in the first position).
    pub repeatability: Option<f64>,
    /// `b`: relative reproducibility (≥ 2 mounting positions).
    pub reproducibility: Option<f64>,
    /// `h`: relative reversibility (series with unloading through this step).
    pub reversibility: Option<f64>,
    /// `f_c`: relative interpolation deviation.
    pub interpolation: f64,
    /// `r`: relative resolution (when a resolution is given).
    pub resolution: Option<f64>,
}

/// DIN 51309 / EURAMET cg-14 figures of a set of series.
#[derive(Debug, Clone, PartialEq)]
pub struct DinReport {
    /// One entry per non-zero torque step, increasing.
    pub steps: Vec<DinStep>,
    /// `f0` per series (`None` for a series without a final zero reading).
    pub zero_error: Vec<Option<f64>>,
    /// Largest `|f0|` over the series.
    pub max_zero_error: Option<f64>,
    /// Interpolation curve `X_a(M) = Σ_k c_k M^k`, lowest order first (`c_0 = 0` through zero).
    pub interpolation_coeffs: Vec<f64>,
    /// Distinct mounting positions, degrees, in order of appearance.
    pub mounting_positions_deg: Vec<f64>,
}

pub(super) struct ParsedSeries {
    mounting_deg: f64,
    zero_before: f64,
    /// (torque, deflection) increasing.
    pub(super) loading: Vec<(f64, f64)>,
    /// Deflection on unloading at each loading step (None where not measured).
    unloading: Vec<Option<f64>>,
    zero_after: Option<f64>,
}

pub(super) fn parse_series(i: usize, s: &LoadSeries) -> Result<ParsedSeries, CalibrationError> {
    let what = format!("series {}", i + 1);
    for (row, st) in s.steps.iter().enumerate() {
        if !st.torque_nm.is_finite() {
            return Err(CalibrationError::NonFiniteRow { what, row, column: "torque_nm" });
        }
        if !st.indication.is_finite() {
            return Err(CalibrationError::NonFiniteRow { what, row, column: "indication" });
        }
    }
    if !s.mounting_deg.is_finite() {
        return Err(invalid(&what, "mounting_deg is not finite"));
    }
    if s.steps.len() < 2 {
        return Err(CalibrationError::TooFewRows { what, needed: 2, got: s.steps.len() });
    }
    if s.steps[0].torque_nm != 0.0 {
        return Err(invalid(&what, "the first step must be the zero reading (torque 0)"));
    }
    let zero_before = s.steps[0].indication;
    let mut loading: Vec<(f64, f64)> = Vec::new();
    let mut unloading_raw: Vec<(f64, f64)> = Vec::new();
    let mut zero_after = None;
    let mut sign = 0.0;
    let mut descending = false;
    for (row, st) in s.steps.iter().enumerate().skip(1) {
        if zero_after.is_some() {
            return Err(invalid(&what, format!("step {} follows the final zero reading", row + 1)));
        }
        let m = st.torque_nm;
        let x = st.indication - zero_before;
        if m == 0.0 {
            if loading.is_empty() {
                return Err(invalid(&what, format!("step {}: a second zero before any load", row + 1)));
            }
            zero_after = Some(st.indication);
            continue;
        }
        if sign == 0.0 {
            sign = m.signum();
        } else if m.signum() != sign {
            return Err(invalid(
                &what,
                format!("step {}: torque changes sign; calibrate each direction separately", row + 1),
            ));
        }
        let prev = if descending { unloading_raw.last().map(|u| u.0) } else { loading.last().map(|l| l.0) };
        match prev {
            Some(p) if !descending && m.abs() > p.abs() => loading.push((m, x)),
            Some(p) if m.abs() < p.abs() => {
                descending = true;
                unloading_raw.push((m, x));
            }
            None => loading.push((m, x)),
            Some(p) => {
                return Err(invalid(
                    &what,
                    format!("step {}: torque {m} N·m after {p} N·m; loading must increase strictly, unloading decrease strictly", row + 1),
                ))
            }
        }
    }
    if loading.is_empty() {
        return Err(invalid(&what, "no loaded step"));
    }
    let mut unloading = vec![None; loading.len()];
    for (m, x) in unloading_raw {
        match loading.iter().position(|l| same_torque(l.0, m)) {
            Some(j) => unloading[j] = Some(x),
            None => return Err(invalid(&what, format!("unloading step {m} N·m is not one of the loading steps"))),
        }
    }
    Ok(ParsedSeries { mounting_deg: s.mounting_deg, zero_before, loading, unloading, zero_after })
}

pub(super) fn same_torque(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
}

fn same_position(a: f64, b: f64) -> bool {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d) < 1e-6
}

/// DIN 51309 / EURAMET cg-14 figures for repeated loading series.
///
/// Deflection `X = indication − zero reading of the same series`. At each non-zero
/// torque step (all series must share the loading steps):
///
/// ```text
/// X̄_wr = mean of X over the series in the first series' mounting position   (usual: (X1 + X2)/2)
/// X̄_r  = mean of X over the first series of each mounting position          (usual: (X1 + X3 + X5)/3)
/// b'   = (max X − min X) / |X̄_wr|  over the same-position series            relative repeatability
/// b    = (max X − min X) / |X̄_r|   over the first series of each position   relative reproducibility
/// h    = mean over series with unloading of |X' − X| / |X̄_r|                relative reversibility
///        (X' unloading, X loading deflection at the step; usual: (|X4'−X3| + |X6'−X5|) / (2 |X̄_r|))
/// f_c  = (X̄_r − X_a) / X_a,  X_a the least-squares polynomial of degree 1–3 in torque
///        through the X̄_r (through zero by default)                          relative interpolation deviation
/// r    = resolution / |X̄_r|                                                  relative resolution
/// ```
///
/// Per series with a final zero reading: `f0 = (i_0,after − i_0,before) / X_top`, the
/// relative zero error, `X_top` the deflection at the series' top step. The top step
/// has no reversibility (loading and unloading meet there).
///
/// No classification is made (the class limits are not encoded here).
///
/// ```
/// use strainwave_analysis::calibration::{din51309_figures, DinOptions, LoadSeries};
/// let s = [
///     LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, 1.000), (0.0, 0.0)]),
///     LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, 1.002), (0.0, 0.0)]),
/// ];
/// let r = din51309_figures(&s, &DinOptions::default()).unwrap();
/// assert!((r.steps[0].repeatability.unwrap() - 0.002 / 1.001).abs() < 1e-12);
/// ```
pub fn din51309_figures(series: &[LoadSeries], opts: &DinOptions) -> Result<DinReport, CalibrationError> {
    if series.is_empty() {
        return Err(CalibrationError::TooFewRows { what: "series".into(), needed: 1, got: 0 });
    }
    if !(1..=3).contains(&opts.interpolation_degree) {
        return Err(invalid("interpolation_degree", format!("must be 1, 2 or 3, got {}", opts.interpolation_degree)));
    }
    if let Some(a) = opts.resolution {
        if !(a.is_finite() && a >= 0.0) {
            return Err(invalid("resolution", format!("must be finite and ≥ 0, got {a}")));
        }
    }
    let parsed: Vec<ParsedSeries> =
        series.iter().enumerate().map(|(i, s)| parse_series(i, s)).collect::<Result<_, _>>()?;
    let levels: Vec<f64> = parsed[0].loading.iter().map(|l| l.0).collect();
    for (i, p) in parsed.iter().enumerate().skip(1) {
        let same = p.loading.len() == levels.len() && p.loading.iter().zip(&levels).all(|(l, m)| same_torque(l.0, *m));
        if !same {
            return Err(invalid(&format!("series {}", i + 1), "its loading steps differ from series 1's"));
        }
    }
    let mut positions: Vec<f64> = Vec::new();
    let mut first_of_position: Vec<usize> = Vec::new();
    for (i, p) in parsed.iter().enumerate() {
        if !positions.iter().any(|&q| same_position(q, p.mounting_deg)) {
            positions.push(p.mounting_deg);
            first_of_position.push(i);
        }
    }
    let same_pos: Vec<usize> =
        (0..parsed.len()).filter(|&i| same_position(parsed[i].mounting_deg, parsed[0].mounting_deg)).collect();

    let spread = |v: &[f64]| {
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        hi - lo
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;

    let mut xr = Vec::with_capacity(levels.len());
    for (j, level) in levels.iter().enumerate() {
        let v: Vec<f64> = first_of_position.iter().map(|&i| parsed[i].loading[j].1).collect();
        let m = mean(&v);
        if m == 0.0 {
            return Err(invalid("series", format!("mean deflection at {level} N·m is zero")));
        }
        xr.push(m);
    }

    // Interpolation curve X_a(M) through the X̄_r.
    let d = opts.interpolation_degree;
    let first_power = usize::from(opts.through_zero);
    let unknowns = d + 1 - first_power;
    if levels.len() < unknowns {
        return Err(CalibrationError::TooFewRows {
            what: "interpolation curve (torque steps)".into(),
            needed: unknowns,
            got: levels.len(),
        });
    }
    let a: Vec<f64> = levels.iter().flat_map(|&m| (first_power..=d).map(move |k| m.powi(k as i32))).collect();
    let sol = lstsq::lstsq(&a, unknowns, &xr)?;
    let mut coeffs = vec![0.0; d + 1];
    coeffs[first_power..].copy_from_slice(&sol.x);
    let curve = |m: f64| coeffs.iter().rev().fold(0.0, |acc, c| acc * m + c);

    let mut steps = Vec::with_capacity(levels.len());
    for (j, &m) in levels.iter().enumerate() {
        let same: Vec<f64> = same_pos.iter().map(|&i| parsed[i].loading[j].1).collect();
        let firsts: Vec<f64> = first_of_position.iter().map(|&i| parsed[i].loading[j].1).collect();
        let x_wr = mean(&same);
        let x_r = xr[j];
        let rev: Vec<f64> =
            parsed.iter().filter_map(|p| p.unloading[j].map(|xu| (xu - p.loading[j].1).abs())).collect();
        let x_a = curve(m);
        steps.push(DinStep {
            torque_nm: m,
            mean_deflection_same_position: x_wr,
            mean_deflection: x_r,
            fitted_deflection: x_a,
            repeatability: (same.len() >= 2).then(|| spread(&same) / x_wr.abs()),
            reproducibility: (firsts.len() >= 2).then(|| spread(&firsts) / x_r.abs()),
            reversibility: (!rev.is_empty()).then(|| mean(&rev) / x_r.abs()),
            interpolation: (x_r - x_a) / x_a,
            resolution: opts.resolution.map(|a| a / x_r.abs()),
        });
    }
    let zero_error: Vec<Option<f64>> = parsed
        .iter()
        .map(|p| {
            let top = p.loading[p.loading.len() - 1].1;
            p.zero_after.map(|z| (z - p.zero_before) / top)
        })
        .collect();
    let max_zero_error = zero_error
        .iter()
        .flatten()
        .map(|f| f.abs())
        .fold(None, |acc: Option<f64>, v| Some(acc.map_or(v, |a| a.max(v))));
    Ok(DinReport { steps, zero_error, max_zero_error, interpolation_coeffs: coeffs, mounting_positions_deg: positions })
}
