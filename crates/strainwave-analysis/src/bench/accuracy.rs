//! The check of fused torques against a reference torque: each method's error figures
//! over a bench record.

use strainwave_core::fusion::{
    AccelerometerModel, ComplementaryFusion, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel,
};

use super::{
    complementary, online_corrected, path_response, spectral_combination, CorrectedFusion, CorrectionConfig,
    ResponseError,
};
use crate::error::AnalysisError;
use crate::frf::{h1, Frf};
use crate::psd::{invalid, SpectralConfig};

/// Settings of [`accuracy_report`].
#[derive(Debug, Clone, PartialEq)]
pub struct AccuracyConfig {
    /// Segmentation of every H1 estimate (calibration and validation).
    pub spectral: SpectralConfig,
    /// Crossover of the complementary filters and the spectral combination, Hz.
    pub crossover_hz: f64,
    /// The corrected fusion's design.
    pub correction: CorrectionConfig,
    /// Torsion path calibration band, Hz.
    pub torsion_band_hz: (f64, f64),
    /// Accelerometer path calibration band, Hz.
    pub accel_band_hz: (f64, f64),
    /// Bins of the calibration H1 below this coherence are not used.
    pub calibration_min_coherence: f64,
    /// Bands the errors are reported in, Hz.
    pub report_bands_hz: Vec<(f64, f64)>,
    /// Validation bins below this coherence are not counted.
    pub validation_min_coherence: f64,
    /// Largest constant delay removed before the phase error is taken (each method and
    /// band its best), s.
    pub max_delay_s: f64,
    /// The bench model of the online corrected fusion: torsion shaft, housing, design.
    pub online_model: (TorsionShaftModel<f64>, AccelerometerModel<f64>, OnlineCorrectionConfig<f64>),
}

impl AccuracyConfig {
    /// For the KIT bench at `sample_rate_hz`: 2¹⁶-sample Hann segments (50 % overlap),
    /// 250 Hz crossover, 32767-tap correction FIRs, calibration of the torsion path from
    /// 0.3 to 600 Hz and of the accelerometers from 100 Hz to 0.45 fs (coherence ≥ 0.9),
    /// report bands 1–20–200–300–1000–4000 Hz, 1 Hz–2 kHz and the whole 1 Hz–4 kHz, delays
    /// up to 1 ms removed, Table I models for the online corrected fusion.
    ///
    /// ```
    /// let c = strainwave_analysis::bench::AccuracyConfig::kit(20_000.0);
    /// assert_eq!(c.report_bands_hz.last(), Some(&(1.0, 4000.0)));
    /// ```
    pub fn kit(sample_rate_hz: f64) -> Self {
        Self {
            spectral: SpectralConfig::new(1 << 16),
            crossover_hz: 250.0,
            correction: CorrectionConfig::new((1 << 15) - 1),
            torsion_band_hz: (0.3, 600.0),
            accel_band_hz: (100.0, 0.45 * sample_rate_hz),
            calibration_min_coherence: 0.9,
            report_bands_hz: vec![
                (1.0, 20.0),
                (20.0, 200.0),
                (200.0, 300.0),
                (300.0, 1000.0),
                (1000.0, 4000.0),
                (1.0, 2000.0),
                (1.0, 4000.0),
            ],
            validation_min_coherence: 0.5,
            max_delay_s: 1e-3,
            online_model: (TorsionShaftModel::kit(), AccelerometerModel::kit(), OnlineCorrectionConfig::kit()),
        }
    }
}

/// Torsion torque, accelerometer torque and a reference torque of one record (N·m, equal
/// lengths).
#[derive(Debug, Clone, Copy)]
pub struct BenchRecord<'a> {
    /// Torsion-shaft torque `T_TS`.
    pub torsion: &'a [f64],
    /// Accelerometer torque `T_acc`.
    pub accel: &'a [f64],
    /// Reference: the model torque (calibration) or the true DUT torque (validation).
    pub reference: &'a [f64],
}

/// One method's errors against the reference, per report band.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodAccuracy {
    /// Method name.
    pub method: &'static str,
    /// Errors per band of [`AccuracyConfig::report_bands_hz`].
    pub bands: Vec<ResponseError>,
}

/// The result of [`accuracy_report`].
#[derive(Debug, Clone)]
pub struct AccuracyReport {
    /// Report bands, Hz.
    pub bands_hz: Vec<(f64, f64)>,
    /// One row per method.
    pub rows: Vec<MethodAccuracy>,
    /// The corrected fusion designed from the calibration record.
    pub fusion: CorrectedFusion,
    /// Calibration H1 of the torsion path (reference → `T_TS`).
    pub torsion_frf: Frf,
    /// Calibration H1 of the accelerometer path (reference → `T_acc`).
    pub accel_frf: Frf,
}

impl AccuracyReport {
    /// The row of `method`.
    pub fn row(&self, method: &str) -> Option<&MethodAccuracy> {
        self.rows.iter().find(|r| r.method == method)
    }

    /// A plain-text table: per method and band, worst `|gain| dB / |phase| °` (each after
    /// its best delay up to [`AccuracyConfig::max_delay_s`]).
    pub fn table(&self) -> String {
        let mut s = format!("{:<30}", "method / band (Hz)");
        for (lo, hi) in &self.bands_hz {
            s += &format!(" | {:>15}", format!("{lo}–{hi}"));
        }
        s += "\n";
        for r in &self.rows {
            s += &format!("{:<30}", r.method);
            for e in &r.bands {
                s += &format!(" | {:>15}", format!("{:.2} dB {:.1}°", e.max_gain_db, e.max_phase_deg));
            }
            s += "\n";
        }
        s
    }
}

/// Method names of [`accuracy_report`], in order.
pub const METHODS: [&str; 7] = [
    "torsion shaft alone",
    "accelerometers alone",
    "complementary, 1st order",
    "complementary, 2nd order",
    "spectral combination (paper)",
    "corrected fusion (FIR)",
    "online corrected (IIR)",
];

/// Calibrates the corrected fusion on `calibration` (H1 of each path against its
/// reference, e.g. the bench's model torque during a sweep), then measures every method
/// on `validation` against its reference (the true DUT torque): H1 from the reference to
/// the method's output, worst gain and phase error per band.
pub fn accuracy_report(
    calibration: BenchRecord<'_>,
    validation: BenchRecord<'_>,
    sample_rate_hz: f64,
    cfg: &AccuracyConfig,
) -> Result<AccuracyReport, AnalysisError> {
    use strainwave_core::fusion::CrossoverOrder;
    let torsion_frf = h1(calibration.reference, calibration.torsion, sample_rate_hz, &cfg.spectral)?;
    let accel_frf = h1(calibration.reference, calibration.accel, sample_rate_hz, &cfg.spectral)?;
    let p_ts =
        path_response(&torsion_frf, cfg.torsion_band_hz.0, cfg.torsion_band_hz.1, cfg.calibration_min_coherence)?;
    let p_acc = path_response(&accel_frf, cfg.accel_band_hz.0, cfg.accel_band_hz.1, cfg.calibration_min_coherence)?;
    let fusion = CorrectedFusion::design(|f| p_ts.at(f), |f| p_acc.at(f), sample_rate_hz, &cfg.correction)?;
    let core_err = |e: strainwave_core::Error| invalid("crossover_hz", e.to_string());
    let first = ComplementaryFusion::new(cfg.crossover_hz, sample_rate_hz, CrossoverOrder::First).map_err(core_err)?;
    let second =
        ComplementaryFusion::new(cfg.crossover_hz, sample_rate_hz, CrossoverOrder::Second).map_err(core_err)?;
    let (m_ts, m_acc, m_cfg) = &cfg.online_model;
    let online = OnlineCorrectedFusion::new(m_ts, m_acc, m_cfg, sample_rate_hz)
        .map_err(|e| invalid("online model", e.to_string()))?;
    let (ts, acc) = (validation.torsion, validation.accel);
    let outputs: [Vec<f64>; 7] = [
        ts.to_vec(),
        acc.to_vec(),
        complementary(ts, acc, &first)?,
        complementary(ts, acc, &second)?,
        spectral_combination(ts, acc, sample_rate_hz, cfg.crossover_hz)?,
        fusion.apply(ts, acc)?,
        online_corrected(ts, acc, &online)?,
    ];
    let mut rows = Vec::with_capacity(METHODS.len());
    for (method, y) in METHODS.iter().zip(&outputs) {
        let frf = h1(validation.reference, y, sample_rate_hz, &cfg.spectral)?;
        let bands = cfg
            .report_bands_hz
            .iter()
            .map(|&(lo, hi)| {
                ResponseError::with_best_delay(&frf, lo, hi, cfg.validation_min_coherence, cfg.max_delay_s)
            })
            .collect::<Result<Vec<_>, _>>()?;
        rows.push(MethodAccuracy { method, bands });
    }
    Ok(AccuracyReport { bands_hz: cfg.report_bands_hz.clone(), rows, fusion, torsion_frf, accel_frf })
}
