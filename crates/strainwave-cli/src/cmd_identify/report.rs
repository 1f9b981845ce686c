//! What `identify` prints and writes to `--summary-json`.

use serde_json::{json, Value};
use strainwave_analysis::ident::{ComplianceFit, FitMetrics, KinematicBasis, KinematicFit};

use super::{Args, ArmConfig, Holdout};

/// Everything the summary reports (fields as computed by `run`).
#[allow(missing_docs)]
pub struct Summary<'a> {
    pub args: &'a Args,
    pub cfg: &'a ArmConfig,
    pub kin: &'a KinematicFit,
    pub cv: Option<f64>,
    pub fit: &'a ComplianceFit,
    pub notes: &'a [String],
    pub holdout: Option<&'a Holdout>,
    pub skipped: usize,
    pub first_skipped: Option<usize>,
    pub rows: usize,
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

impl Summary<'_> {
    fn reference(&self) -> &'static str {
        if self.fit.friction.is_some() {
            "motor-current torque (link torque + friction + rotor inertia × acceleration)"
        } else {
            "link torque"
        }
    }

    fn basis(&self) -> String {
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
        let f = self.fit;
        let v = json!({
            "loaded": self.args.loaded.display().to_string(),
            "no_load": self.args.no_load.as_ref().map(|p| p.display().to_string()),
            "sample_rate_hz": self.sample_rate_hz,
            "rows": self.rows,
            "rows_skipped_non_finite": self.skipped,
            "first_skipped_data_row": self.first_skipped,
            "kinematic": {
                "basis": self.basis(),
                "fit": metrics(&self.kin.metrics),
                "cross_validation_rms_rad": self.cv.map(finite),
                "notes": self.notes,
            },
            "compliance": {
                "spring": self.cfg.compliance.spring,
                "hysteresis": self.cfg.compliance.hysteresis,
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
            "holdout": self.holdout.map(|h| json!({
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

    /// The table printed on stdout.
    pub fn table(&self) -> String {
        let m = &self.kin.metrics;
        let f = &self.fit.metrics;
        let unit = |x: f64, u: &str| if x.is_finite() { format!("{x:.3e} {u}") } else { "-".into() };
        let mut rows = vec![vec![
            "kinematic error (torsion)".to_string(),
            self.basis(),
            format!("{:.4}", m.r_squared),
            unit(m.rms, "rad"),
            "".into(),
        ]];
        if let Some(cv) = self.cv {
            rows.push(vec![
                "  5-fold cross-validation".into(),
                "best candidate".into(),
                "".into(),
                unit(cv, "rad"),
                "".into(),
            ]);
        }
        let solver = match self.fit.termination {
            None => "linear least squares".to_string(),
            Some(t) => format!("{} LM iterations, {}", self.fit.iterations, t.describe()),
        };
        let what = if self.fit.friction.is_some() {
            "compliance + friction (vs current torque)"
        } else {
            "compliance (vs reference)"
        };
        rows.push(vec![
            what.into(),
            format!("{}, {} hysteresis; {solver}", self.cfg.compliance.spring, self.cfg.compliance.hysteresis),
            format!("{:.4}", f.r_squared),
            format!("{:.3} N·m", f.rms),
            format!("{:.1}", f.nrmse_fit_percent()),
        ]);
        if let Some(h) = self.holdout {
            for (name, m) in [("model", &h.model), ("plain linear torsion fit", &h.plain)] {
                rows.push(vec![
                    format!("  {}-block holdout: {name}", h.blocks),
                    "out of sample".into(),
                    format!("{:.4}", m.r_squared),
                    format!("{:.3} N·m", m.rms),
                    format!("{:.1}", m.nrmse_fit_percent()),
                ]);
            }
        }
        let header = ["fit", "model", "R²", "rms", "NRMSE fit %"];
        let mut out = crate::report::text::text_table(&header, &rows);
        out.push_str("parameters (± standard error):\n");
        for p in &self.fit.parameters {
            out.push_str(&format!("  {:<28} {:>12.5e} ± {:.2e}\n", p.name, p.value, p.std_error));
        }
        for n in self.notes {
            out.push_str(&format!("note: {n}\n"));
        }
        if self.skipped > 0 {
            out.push_str(&format!(
                "note: {} rows with non-finite values skipped (--lenient; first at data row {})\n",
                self.skipped,
                self.first_skipped.unwrap_or(0)
            ));
        }
        if let Some(h) = self.holdout {
            if !h.stribeck_speeds_rad_s.is_empty() {
                let v: Vec<String> = h.stribeck_speeds_rad_s.iter().map(|v| v.to_string()).collect();
                out.push_str(&format!(
                    "note: holdout blocks chose Stribeck speeds {} rad/s on their own training rows\n",
                    v.join(", ")
                ));
            }
            if h.unconverged > 0 {
                out.push_str(&format!("note: {} holdout blocks did not converge\n", h.unconverged));
            }
        }
        out.push_str(&format!("model -> {}\n", self.args.out.display()));
        out
    }
}
