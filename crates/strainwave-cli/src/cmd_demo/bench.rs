//! The demo's bench section (hybrid torque sensing after Stoß et al., 2022): Table I
//! figures from the models, then the hybrid fusion methods measured on the bench twin's
//! current sweeps (calibrate on one sweep, validate on another against the true air-gap
//! torque).
//!
//! What limits the corrected fusion is the calibration sweep, not the FIR design: a log
//! sweep of length `T` puts energy `∝ T / f` into each bin, while the errors of the
//! calibration reference (online eq. 12) do not shrink with it. At 1–4 kHz the sweep is
//! fastest and the reference carries the current sensor's noise; at 1–20 Hz the reference
//! leaves out the cogging torque, whose 36/rev line crosses the band as the free rotor
//! creeps (the sweep's first slow half-cycles give it a net impulse). With 12 s sweeps the
//! 1–4 kHz gain error was 1.4 dB and the 1–20 Hz phase error 5.9°; from about 24 s both
//! stay well inside ±1 dB / ±5° (40 s, the library test's length, gains little more).
//! Longer segments make it worse, not better: a sweep excites each bin in one segment only,
//! while every segment adds noise to it; longer FIRs follow the noisier calibration H1
//! more closely.

use std::fmt::Write as _;

use anyhow::Result;
use strainwave_analysis::bench::{accuracy_report, AccuracyConfig, BenchRecord, CorrectionConfig, METHODS};
use strainwave_analysis::bench::{online_corrected, ResponseError};
use strainwave_analysis::frf::h1;
use strainwave_analysis::psd::SpectralConfig;
use strainwave_core::fusion::{
    AccelerometerModel, ComplementaryFusion, CrossoverOrder, OnlineCorrectedFusion, OnlineCorrectionConfig,
    TorsionShaftModel,
};
use strainwave_core::pmsm::LinearPmsm;
use strainwave_sim::bench::{preset, simulate_bench, BenchProfile, SweepSpacing};

use crate::report::html::{esc, table};
use crate::report::plot::{LinePlot, Marker, Series};
use crate::report::text::text_table;

/// Length of each demo sweep, s (see the module doc; the library test uses 40 s).
const SWEEP_S: f64 = 24.0;
/// Lowest sweep frequency, Hz.
const SWEEP_FROM_HZ: f64 = 0.5;
/// Segment of every H1 estimate (2¹⁵ at 20 kHz: 0.61 Hz bins).
const NPERSEG: usize = 1 << 15;
/// Taps of each correction FIR.
const FIR_TAPS: usize = (1 << 14) - 1;
/// The fusions' target: |gain error| dB, |phase error| ° (online: after a delay ≤ 1 ms).
const TARGET: (f64, f64) = (1.0, 5.0);
/// Model errors of the online fusion's robustness curves: `(label, k, J_R, J_B, J_S)` factors.
const MODEL_ERRORS: [(&str, f64, f64, f64, f64); 8] = [
    ("k +10 %", 1.1, 1.0, 1.0, 1.0),
    ("k −10 %", 0.9, 1.0, 1.0, 1.0),
    ("J_R +10 %", 1.0, 1.1, 1.0, 1.0),
    ("J_R −10 %", 1.0, 0.9, 1.0, 1.0),
    ("J_B +10 %", 1.0, 1.0, 1.1, 1.0),
    ("J_B −10 %", 1.0, 1.0, 0.9, 1.0),
    ("J_S +10 %", 1.0, 1.0, 1.0, 1.1),
    ("J_S −10 %", 1.0, 1.0, 1.0, 0.9),
];

fn sweep(seed: u64, amplitude_a: f64) -> Result<strainwave_sim::bench::BenchRecording> {
    let mut s = preset("kit-bench-sweep")?;
    s.seed = seed;
    s.duration_s = SWEEP_S;
    s.profile =
        BenchProfile::CurrentSweep { amplitude_a, from_hz: SWEEP_FROM_HZ, to_hz: 8000.0, spacing: SweepSpacing::Log };
    Ok(simulate_bench(&s, Some(&["torsion_torque", "accel_torque", "inner_torque", "true_dut_torque"]))?)
}

fn col<'a>(r: &'a strainwave_sim::bench::BenchRecording, name: &str) -> Result<&'a [f64]> {
    r.column(name).ok_or_else(|| anyhow::anyhow!("bench twin: no column `{name}`"))
}

/// Text for the terminal, HTML for the report, plots.
pub fn section() -> Result<(String, String, Vec<LinePlot>)> {
    let mut out = String::from("\n== Motor test bench: hybrid torque (torsion shaft + accelerometers) ==\n");
    // Table I figures.
    let ts = TorsionShaftModel::<f64>::kit();
    let acc = AccelerometerModel::<f64>::kit();
    let eq13 = LinearPmsm::<f64>::nanotec_db59().torque_nm(0.0, 2.0);
    let fig_header = ["quantity", "value", "paper"];
    let fig_rows = vec![
        vec!["f_res,TS (torsion shaft)".into(), format!("{:.1} Hz", ts.resonance_hz()), "829.3 Hz".into()],
        vec!["f_res,ACC (housing)".into(), format!("{:.2} Hz", acc.resonance_hz()), "23.73 Hz".into()],
        vec!["G_TS(0) = J_B/(J_B+J_R)".into(), format!("{:.3}", ts.dc_gain()), "0.905".into()],
        vec!["eq. 13, DB59, i_d = 0, i_q = 2 A".into(), format!("{eq13:.4} N·m"), "0.1053 N·m".into()],
    ];
    out += "\n  Table I / II figures from the models:\n";
    out += &text_table(&fig_header, &fig_rows);

    // Fusion accuracy on the twin.
    let fs = preset("kit-bench-sweep")?.sample_rate_hz;
    // The two sweeps are independent: simulate them side by side.
    let (cal, val) = std::thread::scope(|s| {
        let cal = s.spawn(|| sweep(3, 0.1));
        let val = sweep(11, 0.15);
        (cal.join().unwrap_or_else(|e| std::panic::resume_unwind(e)), val)
    });
    let (cal, val) = (cal?, val?);
    let mut cfg = AccuracyConfig::kit(fs);
    cfg.spectral = SpectralConfig::new(NPERSEG);
    cfg.correction = CorrectionConfig::new(FIR_TAPS);
    let (vt, va, vr) = (col(&val, "torsion_torque")?, col(&val, "accel_torque")?, col(&val, "true_dut_torque")?);
    let report = accuracy_report(
        BenchRecord {
            torsion: col(&cal, "torsion_torque")?,
            accel: col(&cal, "accel_torque")?,
            reference: col(&cal, "inner_torque")?,
        },
        BenchRecord { torsion: vt, accel: va, reference: vr },
        fs,
        &cfg,
    )?;
    let mut acc_header: Vec<String> = vec!["method".into()];
    for (lo, hi) in &report.bands_hz {
        acc_header.push(format!("{lo}–{hi} Hz"));
    }
    let acc_rows: Vec<Vec<String>> = report
        .rows
        .iter()
        .map(|r| {
            let mut v = vec![r.method.to_string()];
            v.extend(r.bands.iter().map(|e| format!("{:.2} dB / {:.1}°", e.max_gain_db, e.max_phase_deg)));
            v
        })
        .collect();
    let acc_h: Vec<&str> = acc_header.iter().map(String::as_str).collect();
    let note = format!(
        "  Fusion accuracy: worst |gain error| dB / |phase error| ° of T/T_e per band (H1 against the true\n  \
         air-gap torque, bins with coherence ≥ {}). Calibrated on a {SWEEP_S} s sweep (i_q 0.1 A, {SWEEP_FROM_HZ} Hz–8 kHz,\n  \
         reference: online eq. 12), validated on another (other noise, 0.15 A); {NPERSEG}-sample\n  \
         segments, {FIR_TAPS}-tap FIRs, crossover {} Hz. The calibration sweep's length sets the\n  \
         corrected fusion's accuracy: its energy per bin against the current-sensor noise in the eq. 12\n  \
         reference at 1–4 kHz (where the sweep is fastest) and against the cogging torque eq. 12 leaves\n  \
         out at 1–20 Hz (the free rotor creeps, so the 36/rev cogging line crosses that band). 12 s\n  \
         sweeps miss the target there; 24 s meet it, as the library test's 40 s do.\n",
        cfg.validation_min_coherence, cfg.crossover_hz
    );
    let _ = write!(out, "\n{note}");
    out += &text_table(&acc_h, &acc_rows);
    let band = |lo: f64, hi: f64| report.bands_hz.iter().position(|&b| b == (lo, hi));
    let mut verdict = String::new();
    for (method, lo, hi) in [(METHODS[5], 1.0, 4000.0), (METHODS[6], 1.0, 2000.0), (METHODS[6], 1.0, 4000.0)] {
        if let Some(e) = report.row(method).zip(band(lo, hi)).map(|(r, i)| r.bands[i]) {
            let met = e.max_gain_db <= TARGET.0 && e.max_phase_deg <= TARGET.1;
            let _ = writeln!(
                verdict,
                "  {method} over {lo}–{hi} Hz: {:.2} dB / {:.1}° (worst at {:.0} Hz / {:.0} Hz) after a delay of \
                 {:.3} ms: the ±{} dB / ±{}° target is {}.",
                e.max_gain_db,
                e.max_phase_deg,
                e.worst_gain_hz,
                e.worst_phase_hz,
                e.delay_s * 1e3,
                TARGET.0,
                TARGET.1,
                if met { "met" } else { "NOT met" }
            );
        }
    }
    out += &verdict;

    // Fused responses.
    let spec = SpectralConfig::new(NPERSEG);
    let second = ComplementaryFusion::new(cfg.crossover_hz, fs, CrossoverOrder::Second)?;
    let (m_ts, m_acc, m_cfg) = cfg.online_model;
    let online = OnlineCorrectedFusion::new(&m_ts, &m_acc, &m_cfg, fs)?;
    let outputs: [(&str, Vec<f64>); 5] = [
        (METHODS[0], vt.to_vec()),
        (METHODS[1], va.to_vec()),
        (METHODS[3], strainwave_analysis::bench::complementary(vt, va, &second)?),
        (METHODS[5], report.fusion.apply(vt, va)?),
        (METHODS[6], online_corrected(vt, va, &online)?),
    ];
    let coh = cfg.validation_min_coherence;
    let mut series = Vec::new();
    let mut phase_series = Vec::new();
    for (name, y) in &outputs {
        let f = h1(vr, y, fs, &spec)?;
        series.push(Series {
            name: name.to_string(),
            x: band_points(&f, coh, |h| h.0),
            y: band_points(&f, coh, |h| h.1),
        });
        if *name == METHODS[5] || *name == METHODS[6] {
            let e = ResponseError::with_best_delay(&f, 1.0, 4000.0, coh, cfg.max_delay_s)?;
            let tau = e.delay_s;
            let x = band_points(&f, coh, |h| h.0);
            let p = band_points(&f, coh, |h| h.2 + 360.0 * h.0 * tau);
            let p = p.into_iter().map(|d| (d + 180.0).rem_euclid(360.0) - 180.0).collect();
            phase_series.push(Series { name: format!("{name}, delay {:.3} ms removed", tau * 1e3), x, y: p });
        }
    }
    let plot = LinePlot {
        title: "Fused torque response |T/T_e| on the bench twin (validation sweep)".into(),
        x_label: "frequency (Hz)".into(),
        y_label: "magnitude (dB)".into(),
        series,
        markers: vec![
            Marker { x: acc.resonance_hz(), label: "f_res,ACC".into() },
            Marker { x: cfg.crossover_hz, label: "crossover".into() },
            Marker { x: ts.resonance_hz(), label: "f_res,TS".into() },
        ],
        log_y: false,
        x_range: Some((1.0, 4000.0)),
    };

    let phase_plot = LinePlot {
        title: "Phase of T/T_e on the bench twin: online corrected (IIR) against offline corrected (FIR)".into(),
        x_label: "frequency (Hz)".into(),
        y_label: "phase (°)".into(),
        series: phase_series,
        markers: plot.markers.clone(),
        log_y: false,
        x_range: Some((1.0, 4000.0)),
    };

    // The online fusion with a wrong model.
    let (robust_text, robust_rows, robust_plot) = robustness(&val, fs, &spec, coh, cfg.max_delay_s, &m_cfg)?;
    out += &robust_text;
    out += &text_table(&ROBUST_HEADER, &robust_rows);

    let mut html = String::from("<p>Table I / II figures from the models:</p>");
    html += &table(&fig_header, &fig_rows);
    let _ = write!(html, "<pre>{}</pre>", esc(note.trim_end()));
    html += &table(&acc_h, &acc_rows);
    let _ = write!(html, "<pre>{}</pre>", esc(verdict.trim_end()));
    let _ = write!(html, "<pre>{}</pre>", esc(robust_text.trim()));
    html += &table(&ROBUST_HEADER, &robust_rows);
    let (campbell_text, campbell_svg) = campbell_section()?;
    out += &campbell_text;
    html += &format!("<p>{}</p>", esc(campbell_text.trim()));
    html += &campbell_svg;
    Ok((out, html, vec![plot, phase_plot, robust_plot]))
}

/// `(f, dB, °)` of each bin of 1 Hz … 4 kHz with coherence ≥ `coh`, mapped by `pick`.
fn band_points(f: &strainwave_analysis::frf::Frf, coh: f64, pick: impl Fn((f64, f64, f64)) -> f64) -> Vec<f64> {
    f.freqs_hz
        .iter()
        .zip(&f.h1)
        .zip(&f.coherence)
        .filter(|((fr, _), c)| **fr >= 1.0 && **fr <= 4000.0 && **c >= coh)
        .map(|((fr, h), _)| pick((*fr, 20.0 * h.norm().max(1e-12).log10(), h.arg().to_degrees())))
        .collect()
}

const ROBUST_HEADER: [&str; 3] = ["model error", "1–2000 Hz", "1–4000 Hz"];

/// The online fusion designed from Table I with one parameter off by ±10 %, run on the
/// validation sweep: the note, a table of worst errors and the magnitude curves.
fn robustness(
    val: &strainwave_sim::bench::BenchRecording,
    fs: f64,
    spec: &SpectralConfig,
    coh: f64,
    max_delay_s: f64,
    design: &OnlineCorrectionConfig<f64>,
) -> Result<(String, Vec<Vec<String>>, LinePlot)> {
    let (vt, vr) = (col(val, "torsion_torque")?, col(val, "true_dut_torque")?);
    // The twin's accelerometer torque is J_S α with the true J_S; a wrong J_S scales it.
    let va = col(val, "accel_torque")?;
    let (ts0, acc0) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
    let mut rows = Vec::new();
    let mut series = Vec::new();
    for (label, k, jr, jb, js) in MODEL_ERRORS {
        let mut ts = ts0;
        ts.stiffness_nm_per_rad *= k;
        ts.rotor_inertia_kg_m2 *= jr;
        ts.brake_inertia_kg_m2 *= jb;
        let mut acc = acc0;
        acc.stator_inertia_kg_m2 *= js;
        let f = OnlineCorrectedFusion::new(&ts, &acc, design, fs)?;
        let a_scaled: Vec<f64> = va.iter().map(|v| v * js).collect();
        let y = online_corrected(vt, &a_scaled, &f)?;
        let frf = h1(vr, &y, fs, spec)?;
        let mut row = vec![label.to_string()];
        for hi in [2000.0, 4000.0] {
            let e = ResponseError::with_best_delay(&frf, 1.0, hi, coh, max_delay_s)?;
            row.push(format!("{:.2} dB / {:.1}°", e.max_gain_db, e.max_phase_deg));
        }
        rows.push(row);
        series.push(Series {
            name: label.to_string(),
            x: band_points(&frf, coh, |h| h.0),
            y: band_points(&frf, coh, |h| h.1),
        });
    }
    let text = "\n  Online corrected fusion with a wrong model (one parameter of Table I off by ±10 %, J_S also\n  \
                scaling the accelerometer torque), on the validation sweep: worst |gain error| / |phase error|\n  \
                after each run's best delay ≤ 1 ms. Its poles are those of the crossover pair, whatever the\n  \
                model, so it stays stable; the misplaced shaft notch and the J_S scale cost the most.\n"
        .to_string();
    let plot = LinePlot {
        title: "Online corrected fusion |T/T_e| with a model off by ±10 % (bench twin, validation sweep)".into(),
        x_label: "frequency (Hz)".into(),
        y_label: "magnitude (dB)".into(),
        series,
        markers: vec![
            Marker { x: acc0.resonance_hz(), label: "f_res,ACC".into() },
            Marker { x: ts0.resonance_hz(), label: "f_res,TS".into() },
        ],
        log_y: false,
        x_range: Some((1.0, 4000.0)),
    };
    Ok((text, rows, plot))
}

/// The Campbell diagram of the accelerometer torque over the `kit-bench` ramp
/// (0 → 3200 rpm), with the 6th and 12th electrical orders drawn as lines (mechanical
/// orders `6p` and `12p` for `p` pole pairs).
fn campbell_section() -> Result<(String, String)> {
    use strainwave_analysis::campbell::{campbell, order_hz, CampbellConfig};
    let scenario = preset("kit-bench")?;
    let rec = simulate_bench(&scenario, Some(&["accel_torque", "speed_rpm"]))?;
    let (signal, speed) = (col(&rec, "accel_torque")?, col(&rec, "speed_rpm")?);
    let (nperseg, speed_bin_rpm) = (4096, 50.0);
    let c = campbell(signal, speed, scenario.sample_rate_hz, &CampbellConfig::new(nperseg, speed_bin_rpm))?;
    let amp_db: Vec<Vec<f64>> =
        c.grid.iter().map(|row| row.iter().map(|v| 20.0 * v.max(1e-300).log10()).collect()).collect();
    let (y, z) = crate::report::heatmap::pool_freqs(&c.freqs_hz, &amp_db, 2000.0, 200);
    let pole_pairs = f64::from(scenario.dut.pole_pairs);
    let n_max = c.speed_axis_rpm.last().copied().unwrap_or(0.0) + speed_bin_rpm;
    let top_rpm = speed.iter().copied().fold(0.0_f64, f64::max);
    let orders = [6.0 * pole_pairs, 12.0 * pole_pairs];
    let lines = orders.iter().map(|&o| (format!("{o:.0}×"), vec![(0.0, 0.0), (n_max, order_hz(o, n_max))])).collect();
    let map = crate::report::heatmap::HeatMap {
        title: format!("Campbell diagram of the accelerometer torque, kit-bench ramp 0–{top_rpm:.0} rpm"),
        x_label: "speed (rpm)".into(),
        y_label: "frequency (Hz)".into(),
        z_label: "amplitude (dB re 1 N·m)".into(),
        x: c.speed_axis_rpm.clone(),
        y,
        z,
        range_db: 80.0,
        lines,
    };
    let text = format!(
        "\n  Campbell diagram (report): accelerometer torque over the {:.0} s ramp to {top_rpm:.0} rpm, \
         {nperseg}-sample segments, {speed_bin_rpm:.0} rpm bins; lines at the 6th and 12th electrical \
         orders ({:.0}× and {:.0}× mechanical).\n",
        scenario.duration_s, orders[0], orders[1]
    );
    Ok((text, map.to_svg()))
}

#[cfg(test)]
mod tests {
    /// `cargo test --release -p strainwave-cli --bin strainwave cmd_demo::bench -- --nocapture`
    #[test]
    fn section_prints_the_figures() {
        let t0 = std::time::Instant::now();
        let (text, html, plots) = super::section().unwrap();
        println!("{text}\n({:.1} s)", t0.elapsed().as_secs_f64());
        for s in ["829.3 Hz", "23.73 Hz", "0.905", "0.1053 N·m", "corrected fusion (FIR)", "J_S −10 %"] {
            assert!(text.contains(s), "{s}");
        }
        // Both corrected fusions meet the target: the offline one over 1–4000 Hz, the online
        // one over 1–2000 Hz (after its delay).
        for s in ["corrected fusion (FIR) over 1–4000 Hz", "online corrected (IIR) over 1–2000 Hz"] {
            let line = text.lines().find(|l| l.contains(s)).unwrap_or_else(|| panic!("{s}"));
            assert!(line.ends_with("target is met."), "{line}");
        }
        assert!(html.contains("<table>"));
        assert_eq!(plots.len(), 3);
    }
}
