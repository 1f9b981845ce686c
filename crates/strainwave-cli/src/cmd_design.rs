//! `strainwave design`: bridge sensitivity, full scale, resolution and the placement
//! Monte Carlo for a flexspline sensor.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use strainwave_analysis::stats::histogram;
use strainwave_sim::design::{DesignConfig, DesignReport};

use crate::report::plot::{LinePlot, Series};
use crate::report::text::{compact as fixed, text_table};

/// Arguments of `design`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Sensor design TOML (see examples/sensor-taghirad.toml).
    #[arg(long)]
    pub config: PathBuf,
    /// Write a histogram of the combined 2× residual as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
}

/// The printed report.
pub fn render(r: &DesignReport, full_scale_for_pct: f64) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "sensor design");
    let rows = vec![
        vec!["sensitivity (bridge)".into(), fixed(r.sensitivity_mv_per_v_per_nm, 5), "mV/V per N·m".into()],
        vec!["output at rated torque".into(), fixed(r.output_at_rated_mv_per_v, 4), "mV/V".into()],
        vec!["sensitivity after amplifier".into(), fixed(r.amplified_v_per_nm, 5), "V per N·m".into()],
        vec!["calibration gain".into(), fixed(1.0 / r.amplified_v_per_nm, 4), "N·m/V".into()],
        vec!["full scale (ADC range)".into(), fixed(r.full_scale_nm, 2), "N·m".into()],
        vec!["resolution (1 LSB)".into(), fixed(r.resolution_nm, 5), "N·m".into()],
        vec!["principal strain at rated torque".into(), fixed(r.strain_at_rated_microstrain, 1), "µε".into()],
        vec!["2× residual, ideal placement".into(), format!("{:.2e}", r.ideal_residual_nm.0), "N·m".into()],
        vec!["4× residual, ideal placement".into(), fixed(r.ideal_residual_nm.1, 4), "N·m".into()],
    ];
    out += &text_table(&["figure", "value", "unit"], &rows);
    let _ = writeln!(out, "\nresidual interference from placement errors (Monte Carlo), N·m and % of full scale:");
    let pct = |x: f64| 100.0 * x / full_scale_for_pct;
    let mut mc = Vec::new();
    for s in &r.studies {
        for (line, p) in [("2×", s.line_2x_nm), ("4×", s.line_4x_nm)] {
            mc.push(vec![
                s.errors.to_string(),
                line.to_string(),
                fixed(p.p50, 4),
                fixed(p.p95, 4),
                fixed(p.p99, 4),
                fixed(pct(p.p95), 3),
            ]);
        }
    }
    out += &text_table(&["errors", "line", "p50 N·m", "p95 N·m", "p99 N·m", "p95 % FS"], &mc);
    out
}

/// Runs `design`.
pub fn run(a: &Args) -> Result<()> {
    if let Some(svg) = &a.svg {
        strainwave_io::output::refuse_input_as_output(svg, [a.config.as_path()])?;
    }
    let text = std::fs::read_to_string(&a.config).with_context(|| format!("{}", a.config.display()))?;
    // Parsed here rather than by `DesignConfig::from_toml` so that a type error names the
    // file, line and key as the other configuration readers do.
    let cfg: DesignConfig =
        toml::from_str(&text).map_err(|e| strainwave_joint::toml_error::one_line(&a.config, &text, &e))?;
    cfg.validate().with_context(|| format!("config {}", a.config.display()))?;
    let r = cfg.evaluate().with_context(|| format!("config {}", a.config.display()))?;
    let mut out = render(&r, r.full_scale_nm);
    let _ = writeln!(
        out,
        "\n({} draws, seed {}, tolerances 1σ: radial {} mm, circumferential {}°, angular {}°)",
        cfg.monte_carlo.draws,
        cfg.monte_carlo.seed,
        cfg.sensor.placement_tolerance.radial_mm,
        cfg.sensor.placement_tolerance.circumferential_deg,
        cfg.sensor.placement_tolerance.angular_deg
    );
    if let Some(path) = &a.svg {
        let combined = r.studies.iter().find(|s| s.errors == "combined").context("no combined study")?;
        let (edges, counts) = histogram(&combined.samples_2x_nm, 50);
        let mut x = Vec::with_capacity(2 * counts.len());
        let mut y = Vec::with_capacity(2 * counts.len());
        for (i, c) in counts.iter().enumerate() {
            x.extend_from_slice(&[edges[i], edges[i + 1]]);
            y.extend_from_slice(&[*c as f64, *c as f64]);
        }
        let plot = LinePlot {
            title: "Residual 2× interference over placement draws (combined tolerances)".into(),
            x_label: "2× residual amplitude (N·m)".into(),
            y_label: "draws per bin".into(),
            series: vec![Series { name: format!("{} draws", combined.samples_2x_nm.len()), x, y }],
            ..Default::default()
        };
        strainwave_io::output::write_file(path, plot.to_svg())?;
        let _ = writeln!(out, "wrote {}", path.display());
    }
    crate::stdout::print_report(&out, [a.svg.as_deref()])
}
