//! What `identify` reports: the fits, their parameters and the holdout scores, as the
//! JSON of `--summary-json` (the command line prints them as a table too).

use serde_json::{json, Value};
use strainwave_analysis::ident::{ComplianceFit, FitMetrics, KinematicBasis, KinematicFit};

use super::Holdout;

/// Everything the summary reports, as [`super::identify`] computed it.
#[derive(Debug, Clone)]
pub struct Summary {
    /// The loaded run, as messages name it.
    pub loaded: String,
    /// The no-load run, when there is one.
    pub no_load: Option<String>,
    /// The configured spring (`compliance.spring`).
    pub spring: String,
    /// The configured hysteresis (`compliance.hysteresis`).
    pub hysteresis: String,
    /// The kinematic-error fit.
    pub kin: KinematicFit,
    /// The best cross-validation RMS when the order was chosen by cross-validation, rad.
    pub cv: Option<f64>,
    /// The compliance fit.
    pub fit: ComplianceFit,
    /// What was not identifiable or chosen, and why.
    pub notes: Vec<String>,
    /// The holdout scores (`--holdout`).
    pub holdout: Option<Holdout>,
    /// Rows skipped for non-finite values (`--lenient`).
    pub skipped: usize,
    /// First skipped data row (1-based).
    pub first_skipped: Option<usize>,
    /// The file and row of the first skipped row, as messages name it.
    pub first_skipped_at: Option<String>,
    /// Rows of the loaded run used.
    pub rows: usize,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
}

fn finite(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

fn metrics(m: &FitMetrics) -> Value {
    json!({
        "r_squared": finite(m.r_squared),
        "rms": finite(m.rms),
        "nrmse_fit_percent": finite(m.nrmse_fit_percent()),
        "max_abs": finite(m.max_abs),
        "samples": m.samples,
    })
}

impl Summary {
    /// What the compliance fit's reference torque is.
    pub fn reference(&self) -> &'static str {
        if self.fit.friction.is_some() {
            "motor-current torque (link torque + friction + rotor inertia × acceleration)"
        } else {
            "link torque"
        }
    }

    /// The kinematic basis in words.
    pub fn basis(&self) -> String {
        match self.kin.basis {
            KinematicBasis::Polynomial { order } => format!("polynomial, order {order}"),
            KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 0, .. } => "none".into(),
            KinematicBasis::Fourier { output_harmonics, mesh_harmonics, mesh_angle } => {
                format!("Fourier, {output_harmonics} output + {mesh_harmonics} mesh harmonics ({mesh_angle:?} angle)")
            }
        }
    }

    /// The JSON summary.
    pub fn json(&self) -> String {
        let f = &self.fit;
        let v = json!({
            "loaded": self.loaded,
            "no_load": self.no_load,
            "sample_rate_hz": self.sample_rate_hz,
            "rows": self.rows,
            "rows_skipped": self.skipped,
            "first_skipped_data_row": self.first_skipped,
            "kinematic": {
                "basis": self.basis(),
                "fit": metrics(&self.kin.metrics),
                "cross_validation_rms_rad": self.cv.map(finite),
                "notes": self.notes,
            },
            "compliance": {
                "spring": self.spring,
                "hysteresis": self.hysteresis,
                "reference": self.reference(),
                "solver": if f.termination.is_some() { "levenberg-marquardt" } else { "linear least squares" },
                "termination": f.termination,
                "converged": f.converged(),
                "iterations": f.iterations,
                "parameters": f.parameters.iter().map(|p| json!({
                    "name": p.name, "value": finite(p.value), "std_error": finite(p.std_error)
                })).collect::<Vec<_>>(),
                "fit": metrics(&f.metrics),
            },
            "holdout": self.holdout.as_ref().map(|h| json!({
                "blocks": h.blocks,
                "model": metrics(&h.model),
                "plain_linear": metrics(&h.plain),
                "unconverged_blocks": h.unconverged,
                "stribeck_speeds_rad_s": h.stribeck_speeds_rad_s,
            })),
        });
        let mut s = serde_json::to_string_pretty(&v).unwrap_or_default();
        s.push('\n');
        s
    }
}
