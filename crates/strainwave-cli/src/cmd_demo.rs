//! `strainwave demo`: the main job on the embedded default. Simulates the Taghirad
//! joint, prints what was simulated and the ripple it carries, writes the report.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use strainwave_analysis::lines::find_lines;
use strainwave_analysis::spectrum::amplitude_spectrum;
use strainwave_analysis::stats::{max_abs, mean, rms, time_window};
use strainwave_sim::{presets, simulate};

use crate::report::html::{esc, table, Report, Section};
use crate::report::plot::{LinePlot, Marker, Series};
use crate::report::text::text_table;

mod bench;
mod calibration;
mod estimate;

/// Arguments of `demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Directory for report.html and the simulated recording.
    #[arg(long, default_value = "strainwave-demo")]
    pub out: PathBuf,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs `demo`.
pub fn run(a: &Args) -> Result<()> {
    let scenario = presets::preset("taghirad")?;
    let (rec, sim) = simulate(&scenario)?;
    let col = |name: &str| rec.column(name).with_context(|| format!("simulator did not produce `{name}`"));
    let time = col("time")?;
    let sensor = sim.sensor();
    let fs = scenario.sample_rate_hz;
    let full_scale = sensor.full_scale_nm();
    let pct = |x: f64| 100.0 * x / full_scale;

    // What the joint carries.
    let ripple = col("true_ripple")?;
    let mis = col("true_misalignment")?;
    let torque = col("true_torque")?;
    let measured = col("measured_torque")?;

    // Ripple lines in the first constant-speed window.
    let (t0, t1, speed) =
        scenario.hold_windows(0.2).first().copied().context("the demo scenario has no constant-speed hold")?;
    let w = time_window(time, t0, t1);
    let phi = &col("true_relative_angle")?[w.clone()];
    let rel_rate = (phi[phi.len() - 1] - phi[0]) / (phi.len() - 1) as f64 * fs;
    let out_rate = mean(&col("true_output_velocity")?[w.clone()]);
    let tau = std::f64::consts::TAU;
    let expected = vec![
        ("2× relative angle".to_string(), 2.0 * rel_rate.abs() / tau),
        ("4× relative angle".to_string(), 4.0 * rel_rate.abs() / tau),
    ];
    let lines = find_lines(&measured[w.clone()], fs, &expected, 2)?;

    let mut out = String::new();
    let _ = writeln!(out, "strainwave demo: the Taghirad joint (preset `taghirad`), simulated");
    let _ = writeln!(
        out,
        "  {:.0}:1 strain wave gear, circular spline fixed, {:.0} N·m rated; four-rosette bridge, {} V excitation, gain {}, {}-bit ADC",
        scenario.gear.ratio, scenario.gear.rated_torque_nm, scenario.sensor.excitation_v, scenario.sensor.amplifier_gain, scenario.sensor.adc_bits
    );
    let _ = writeln!(
        out,
        "  {:.1} s at {} Hz: motor to {:.0} rad/s, hold, reversal to {:.0} rad/s, hold; RK4 sub-steps per sample: {}",
        scenario.duration_s,
        fs,
        scenario.top_motor_speed_rad_s(),
        -scenario.top_motor_speed_rad_s(),
        sim.substeps()
    );
    let _ = writeln!(
        out,
        "  sensor: gain {:.3} N·m/V (Taghirad and Bélanger 1999: 6.60), full scale {:.1} N·m, white-noise floor {:.4} N·m rms\n",
        sensor.gain_nm_per_v().abs(),
        full_scale,
        sensor.noise_floor_nm()
    );
    let intro = out.clone();
    let rows = vec![
        vec![
            "transmitted torque (true)".into(),
            format!("{:.3}", max_abs(torque)),
            format!("{:.3}", rms(torque)),
            format!("{:.2}", pct(max_abs(torque))),
        ],
        vec![
            "ripple, 2× + 4× (meshing + interference)".into(),
            format!("{:.3}", max_abs(ripple)),
            format!("{:.3}", rms(ripple)),
            format!("{:.2}", pct(max_abs(ripple))),
        ],
        vec![
            "misalignment, 1× output".into(),
            format!("{:.3}", max_abs(mis)),
            format!("{:.3}", rms(mis)),
            format!("{:.2}", pct(max_abs(mis))),
        ],
        vec![
            "white noise + quantization".into(),
            "".into(),
            format!("{:.4}", sensor.noise_floor_nm()),
            format!("{:.3}", pct(sensor.noise_floor_nm())),
        ],
    ];
    let header = ["component", "peak N·m", "rms N·m", "peak % FS"];
    out += &text_table(&header, &rows);
    let _ = writeln!(
        out,
        "\n  ripple lines in the measured torque, {t0:.1}–{t1:.1} s at {speed:.0} rad/s (bin {:.2} Hz):",
        lines[0].resolution_hz
    );
    let line_rows: Vec<Vec<String>> = lines
        .iter()
        .map(|l| {
            vec![
                l.label.clone(),
                format!("{:.2}", l.expected_hz),
                format!("{:.2}", l.found_hz),
                format!("{:+}", l.offset_bins.round() as i64),
                format!("{:.3}", l.amplitude),
                if l.is_peak { "yes".into() } else { "no".into() },
            ]
        })
        .collect();
    let line_header = ["order", "expected Hz", "found Hz", "offset bins", "amplitude N·m", "peak"];
    out += &text_table(&line_header, &line_rows);
    let _ = writeln!(
        out,
        "  (in rad/s: 2× at {:.0}, 4× at {:.0}; the paper's Fig. 8 shows 312 and 624 at 156 rad/s; misalignment at {:.3} Hz)",
        2.0 * rel_rate.abs(),
        4.0 * rel_rate.abs(),
        out_rate.abs() / tau
    );

    // The canceller against its alternatives, on three runs.
    let (acc_text, acc_html, acc_plots) = canceller_section()?;
    out += &acc_text;
    let (cal_text, cal_html, cal_plots) = calibration::section()?;
    out += &cal_text;
    let (est_text, est_html, est_plots) = estimate::section()?;
    out += &est_text;
    let (bench_text, bench_html, bench_plots) = bench::section()?;
    out += &bench_text;

    // Report.
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("{}: cannot create the output directory", a.out.display()))?;
    let rec_path = a.out.join("taghirad.csv");
    {
        let mut wtr = strainwave_io::CsvWriter::create(&rec_path, &rec.columns)?;
        let mut row = vec![0.0; rec.columns.len()];
        for k in 0..time.len() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = rec.data[c][k];
            }
            wtr.write_row(&row)?;
        }
        wtr.finish()?;
    }
    let time_plot = LinePlot {
        title: "Measured and true torque, taghirad preset".into(),
        x_label: "time (s)".into(),
        y_label: "output torque (N·m)".into(),
        series: vec![
            Series { name: "measured (calibrated bridge)".into(), x: time.to_vec(), y: measured.to_vec() },
            Series { name: "true transmitted torque".into(), x: time.to_vec(), y: torque.to_vec() },
        ],
        ..Default::default()
    };
    let zoom = LinePlot {
        title: format!("Zoom at constant speed, {:.2}–{:.2} s", t0 + 0.3, t0 + 0.5),
        x_range: Some((t0 + 0.3, t0 + 0.5)),
        ..time_plot.clone()
    };
    let spec = amplitude_spectrum(&measured[w.clone()], fs)?;
    let mut markers: Vec<Marker> =
        lines.iter().map(|l| Marker { x: l.expected_hz, label: l.label.replace(" relative angle", "") }).collect();
    markers.push(Marker { x: 6.0 * rel_rate.abs() / tau, label: "6×".into() });
    let spec_plot = LinePlot {
        title: format!("Amplitude spectrum of the measured torque at {speed:.0} rad/s (Hann, {t0:.1}–{t1:.1} s)"),
        x_label: "frequency (Hz)".into(),
        y_label: "amplitude (N·m)".into(),
        series: vec![Series { name: "measured torque".into(), x: spec.freqs_hz.clone(), y: spec.amplitude.clone() }],
        markers,
        log_y: true,
        ..Default::default()
    };
    let html_rows: Vec<Vec<String>> = rows.iter().map(|r| r.to_vec()).collect();
    let mut body = format!("<pre>{}</pre>", esc(intro.trim_end()));
    body += &table(&header, &html_rows);
    body += &table(&line_header, &line_rows);
    body += &time_plot.to_svg();
    body += &zoom.to_svg();
    body += &spec_plot.to_svg();
    let mut acc_body = acc_html;
    for p in &acc_plots {
        acc_body += &p.to_svg();
    }
    let report = Report {
        title: "strainwave demo report".into(),
        subtitle: format!("Taghirad joint (preset `taghirad`), strainwave {}", env!("CARGO_PKG_VERSION")),
        sections: vec![
            Section { title: "Joint digital twin".into(), body },
            Section { title: "Ripple and misalignment cancellation".into(), body: acc_body },
            Section {
                title: "Sensor calibration".into(),
                body: cal_html + &cal_plots.iter().map(LinePlot::to_svg).collect::<String>(),
            },
            Section {
                title: "Link torque from two encoders".into(),
                body: est_html + &est_plots.iter().map(LinePlot::to_svg).collect::<String>(),
            },
            Section {
                title: "Motor test bench: hybrid torque".into(),
                body: bench_html + &bench_plots.iter().map(LinePlot::to_svg).collect::<String>(),
            },
        ],
    };
    let report_path = a.out.join("report.html");
    strainwave_io::output::write_file(&report_path, report.to_html())?;
    if !a.quiet {
        out += &format!("\nwrote {} and {}\n", report_path.display(), rec_path.display());
        crate::stdout::print(&out)?;
    }
    Ok(())
}

/// Accuracy of the canceller and its alternatives on the free-motion, standstill and
/// loaded runs: text, HTML table and plots. The full configuration first learns on the
/// commissioning run of the same joint.
fn canceller_section() -> Result<(String, String, Vec<LinePlot>)> {
    use strainwave_analysis::canceller_eval::{
        commission, evaluate, filtered, guarded, lowpass_cutoff_for, smoothed, smoothed_accuracy, worst_window_ratio,
        Method,
    };
    let mut text = String::from("\nripple and misalignment cancellation against the simulator's truth:\n");
    let commissioning = EvalRun::simulate("taghirad-commissioning")?;
    let learned = commission(&commissioning.signals()?, &commissioning.gear, commissioning.noise_nm)?;
    text += &format!(
        "  the full configuration learned its coefficients on `taghirad-commissioning` ({:.0} s at 156 rad/s, \
         load levels 0/+8/-8/+4/0 N·m, other noise), then filters each run from them;\n  \
         misalignment learned {:.3} N·m peak (true {:.3}); `no commissioning` learns from zero during the run.\n",
        commissioning.duration_s,
        learned[4].0[0].hypot(learned[4].0[1]),
        commissioning.misalignment_peak_nm,
    );
    let header = ["run", "method", "ripple+mis left dB", "RMS err N·m", "RMS err % FS", "step delay samples"];
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut plots = Vec::new();
    let mut lowpass_hz = None;
    let mut lowpass_note = String::new();
    // Never worse than raw: the guarded filter's worst 1 s window, cold and commissioned.
    let mut harm_rows: Vec<Vec<String>> = Vec::new();
    for name in ["taghirad", "taghirad-standstill", "taghirad-loaded"] {
        let run = EvalRun::simulate(name)?;
        let signals = run.signals()?;
        let (gear, noise) = (run.gear, run.noise_nm);
        // The low-pass gets the cutoff that matches the full configuration's suppression
        // on the free-motion run, and keeps it on the other runs.
        let full = evaluate(&signals, &gear, noise, &[Method::Full], 0.3, Some(&learned))?;
        let fc = *lowpass_hz.get_or_insert(lowpass_cutoff_for(&signals, full[0].suppression_db)?);
        let f2 = 2.0 * run.top_relative_speed_rad_s / std::f64::consts::TAU;
        let methods = [
            Method::Raw,
            Method::LowPass(fc),
            Method::Notch(f2),
            Method::Taghirad4th,
            Method::Taghirad6th,
            Method::FullCold,
            Method::Full,
            Method::Smoothed,
        ];
        let eval = evaluate(&signals, &gear, noise, &methods, 0.3, Some(&learned))?;
        if let (Some(lp), true) = (eval.get(1), name == "taghirad") {
            if lp.suppression_db < full[0].suppression_db - 3.0 {
                lowpass_note = format!(
                    "  no 2nd-order low-pass reaches the full configuration's {:.1} dB: the misalignment line is at \
                     {:.2} Hz, so its cutoff stops at the search's floor, {fc:.1} Hz ({:.1} dB).\n",
                    full[0].suppression_db,
                    run.top_relative_speed_rad_s / run.gear_ratio / std::f64::consts::TAU,
                    lp.suppression_db
                );
            }
        }
        for r in &eval {
            rows.push(vec![
                name.to_string(),
                r.method.label(),
                format!("{:.1}", r.suppression_db),
                format!("{:.4}", r.rms_error_nm),
                format!("{:.3}", 100.0 * r.rms_error_nm / run.full_scale_nm),
                r.step_delay_samples.map_or(format!("> {}", signals.measured_nm.len() / 2), |d| d.to_string()),
            ]);
        }
        let worst = |learned| -> Result<String> {
            Ok(format!("{:.2}×", worst_window_ratio(&guarded(&signals, &gear, noise, learned)?, &signals)?))
        };
        harm_rows.push(vec![name.to_string(), "1.00×".into(), worst(None)?, worst(Some(&learned))?]);
        let full_row = eval.iter().find(|r| r.method == Method::Full).context("no full row")?;
        let smoothed_row = eval.last().context("no rows")?;
        let band = smoothed_accuracy(&signals, &gear, noise, &learned, 0.3, None)?;
        rows.push(vec![
            name.to_string(),
            "(white-noise floor)".into(),
            "".into(),
            format!("{noise:.4}"),
            format!("{:.3}", 100.0 * noise / run.full_scale_nm),
            format!(
                "full/floor = {:.2}, smoothed/floor = {:.2} (±1σ covers {:.0} %)",
                full_row.rms_error_nm / noise,
                smoothed_row.rms_error_nm / noise,
                100.0 * band.coverage_1sd
            ),
        ]);
        if name == "taghirad" {
            // Spectrum before and after, over the first constant-speed hold.
            let t = run.col("time")?;
            let clean = filtered(&signals, &gear, noise, &learned)?;
            let w = time_window(t, 0.6, 2.0);
            let spectrum = |name: &str, x: &[f64]| -> Result<Series> {
                let sp = amplitude_spectrum(&x[w.clone()], run.sample_rate_hz)?;
                Ok(Series { name: name.into(), x: sp.freqs_hz, y: sp.amplitude })
            };
            plots.push(LinePlot {
                title: "Free-motion run, 0.6–2.0 s at 156 rad/s: spectrum before and after the canceller (Hann)".into(),
                x_label: "frequency (Hz)".into(),
                y_label: "amplitude (N·m)".into(),
                series: vec![
                    spectrum("measured", signals.measured_nm)?,
                    spectrum("strainwave filtered", &clean)?,
                    spectrum("true", signals.true_torque_nm)?,
                ],
                markers: [2.0, 4.0].iter().map(|n| Marker { x: n * f2 / 2.0, label: format!("{n:.0}×") }).collect(),
                log_y: true,
                x_range: Some((0.0, 150.0)),
            });
        }
        if name == "taghirad-loaded" {
            let t = run.col("time")?;
            let clean = filtered(&signals, &gear, noise, &learned)?;
            let offline = smoothed(&signals, &gear, noise, &learned)?;
            plots.push(LinePlot {
                title: "Loaded run: measured, filtered, smoothed (offline) and true torque".into(),
                x_label: "time (s)".into(),
                y_label: "output torque (N·m)".into(),
                series: vec![
                    Series { name: "measured".into(), x: t.to_vec(), y: signals.measured_nm.to_vec() },
                    Series { name: "strainwave filtered".into(), x: t.to_vec(), y: clean },
                    Series { name: "strainwave smoothed".into(), x: t.to_vec(), y: offline },
                    Series { name: "true".into(), x: t.to_vec(), y: signals.true_torque_nm.to_vec() },
                ],
                x_range: Some((2.3, 2.8)),
                ..Default::default()
            });
        }
    }
    text += &text_table(&header, &rows);
    text += &lowpass_note;
    let harm_header = ["run", "raw", "cold (no learned file)", "commissioned"];
    text += "\n  the guarded filter as `strainwave filter` runs it: worst 1 s window after the first, RMS error \
             against the truth over the raw signal's (1.00× = never worse than raw):\n";
    text += &text_table(&harm_header, &harm_rows);
    let html = crate::report::html::table(&header, &rows) + &crate::report::html::table(&harm_header, &harm_rows);
    Ok((text, html, plots))
}

/// One simulated run of the canceller table.
struct EvalRun {
    rec: strainwave_sim::Recording,
    gear: strainwave_core::gear::Gear<f64>,
    noise_nm: f64,
    full_scale_nm: f64,
    sample_rate_hz: f64,
    duration_s: f64,
    top_relative_speed_rad_s: f64,
    gear_ratio: f64,
    misalignment_peak_nm: f64,
}

impl EvalRun {
    fn simulate(preset: &str) -> Result<Self> {
        let scenario = presets::preset(preset)?;
        let (rec, sim) = simulate(&scenario)?;
        Ok(Self {
            rec,
            gear: sim.model().gear,
            noise_nm: sim.sensor().noise_floor_nm(),
            full_scale_nm: sim.sensor().full_scale_nm(),
            sample_rate_hz: scenario.sample_rate_hz,
            duration_s: scenario.duration_s,
            top_relative_speed_rad_s: scenario.top_motor_speed_rad_s() * (1.0 + 1.0 / scenario.gear.ratio),
            gear_ratio: scenario.gear.ratio,
            misalignment_peak_nm: scenario.misalignment.amplitude_nm,
        })
    }

    fn col(&self, c: &str) -> Result<&[f64]> {
        self.rec.column(c).with_context(|| format!("simulator did not produce `{c}`"))
    }

    fn signals(&self) -> Result<strainwave_analysis::canceller_eval::RunSignals<'_>> {
        Ok(strainwave_analysis::canceller_eval::RunSignals {
            sample_rate_hz: self.sample_rate_hz,
            measured_nm: self.col("measured_torque")?,
            motor_angle_rad: self.col("motor_angle")?,
            output_angle_rad: self.col("output_angle")?,
            motor_velocity_rad_s: self.col("motor_velocity")?,
            true_torque_nm: self.col("true_torque")?,
            true_ripple_nm: self.col("true_ripple")?,
            true_misalignment_nm: self.col("true_misalignment")?,
        })
    }
}
