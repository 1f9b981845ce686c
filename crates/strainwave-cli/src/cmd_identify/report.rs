//! The table `identify` prints on stdout.

use std::path::Path;

use strainwave_joint::identify::Summary;

/// The fits, parameters and notes of `s` as a table, ending with where the model went.
pub fn table(s: &Summary, model_path: &Path) -> String {
    let m = &s.kin.metrics;
    let f = &s.fit.metrics;
    let unit = |x: f64, u: &str| if x.is_finite() { format!("{x:.3e} {u}") } else { "-".into() };
    // No fit (a kinematic error of none) has no R².
    let r2 = |x: f64| if x.is_finite() { format!("{x:.4}") } else { "-".into() };
    let mut rows =
        vec![vec!["kinematic error (torsion)".to_string(), s.basis(), r2(m.r_squared), unit(m.rms, "rad"), "".into()]];
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
        r2(f.r_squared),
        format!("{:.3} N·m", f.rms),
        format!("{:.1}", f.nrmse_fit_percent()),
    ]);
    if let Some(h) = &s.holdout {
        for (name, m) in [("model", &h.model), ("plain linear torsion fit", &h.plain)] {
            rows.push(vec![
                format!("  {}-block holdout: {name}", h.blocks),
                "out of sample".into(),
                r2(m.r_squared),
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
    // Signs a physical reading would not have: these terms take up something else.
    let negative = |name: &str| s.fit.parameters.iter().find(|p| p.name == name && p.value + 2.0 * p.std_error < 0.0);
    if let Some(p) = negative("inertia_kg_m2") {
        out.push_str(&format!(
            "note: inertia_kg_m2 {:.3} is negative: the acceleration term takes up a lag of the log (the causal \
             differences of its angles), not a rotor inertia; see docs/real-arm.md\n",
            p.value
        ));
    }
    if let Some(p) = negative("coulomb_nm") {
        out.push_str(&format!(
            "note: coulomb_nm {:.3} is negative: with stribeck_nm the friction terms draw a curve that rises with \
             speed; read them together as that shape, not as Coulomb and Stribeck levels\n",
            p.value
        ));
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
