//! The table `identify` prints on stdout.

use std::path::Path;

use strainwave_joint::identify::Summary;

/// The fits, parameters and notes of `s` as a table, ending with where the model went.
pub fn table(s: &Summary, model_path: &Path) -> String {
    let m = &s.kin.metrics;
    let f = &s.fit.metrics;
    let unit = |x: f64, u: &str| if x.is_finite() { format!("{x:.3e} {u}") } else { "-".into() };
    let mut rows = vec![vec![
        "kinematic error (torsion)".to_string(),
        s.basis(),
        format!("{:.4}", m.r_squared),
        unit(m.rms, "rad"),
        "".into(),
    ]];
    if let Some(cv) = s.cv {
        rows.push(vec![
            "  5-fold cross-validation".into(),
            "best candidate".into(),
            "".into(),
            unit(cv, "rad"),
            "".into(),
        ]);
    }
    let solver = match s.fit.termination {
        None => "linear least squares".to_string(),
        Some(t) => format!("{} LM iterations, {}", s.fit.iterations, t.describe()),
    };
    let what = if s.fit.friction.is_some() {
        "compliance + friction (vs current torque)"
    } else {
        "compliance (vs reference)"
    };
    rows.push(vec![
        what.into(),
        format!("{}, {} hysteresis; {solver}", s.spring, s.hysteresis),
        format!("{:.4}", f.r_squared),
        format!("{:.3} N·m", f.rms),
        format!("{:.1}", f.nrmse_fit_percent()),
    ]);
    if let Some(h) = &s.holdout {
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
    for p in &s.fit.parameters {
        out.push_str(&format!("  {:<28} {:>12.5e} ± {:.2e}\n", p.name, p.value, p.std_error));
    }
    for n in &s.notes {
        out.push_str(&format!("note: {n}\n"));
    }
    if s.skipped > 0 {
        out.push_str(&format!(
            "note: {} rows with unusable values skipped (--lenient; first at {})\n",
            s.skipped,
            s.first_skipped_at.as_deref().unwrap_or("-")
        ));
    }
    if let Some(h) = &s.holdout {
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
    out.push_str(&format!("model -> {}\n", model_path.display()));
    out
}
