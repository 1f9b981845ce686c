//! `strainwave orders`: amplitude and phase of orders against speed (angle-domain blocks),
//! as a table on standard output (standard error when the SVG plot of the amplitudes goes
//! there) and that plot.

use std::path::PathBuf;

use anyhow::{bail, Result};
use strainwave_analysis::campbell::{order_slice, OrderSliceConfig};

use crate::recording_args::{SignalArgs, SpeedArgs};
use crate::report::plot::{LinePlot, Series};
use crate::report::text::text_table;

/// Arguments of `orders`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub source: SignalArgs,
    #[command(flatten)]
    pub speed: SpeedArgs,
    /// Order (mechanical, cycles per revolution); repeat for several.
    #[arg(long = "order", required = true)]
    pub orders: Vec<f64>,
    /// Revolutions per analysis block.
    #[arg(long, default_value_t = 8.0)]
    pub revs_per_block: f64,
    /// Width of a speed bin of the table, rpm.
    #[arg(long, default_value_t = 200.0)]
    pub speed_bin: f64,
    /// Output SVG (amplitude vs speed).
    #[arg(long)]
    pub out: PathBuf,
}

/// Per speed bin: mean amplitude and circular mean phase of the blocks in it.
fn bin(s: &strainwave_analysis::campbell::OrderSlice, width: f64, nbins: usize) -> Vec<Option<(f64, f64)>> {
    let mut acc = vec![(0.0, 0.0, 0.0, 0usize); nbins];
    for i in 0..s.speed_rpm.len() {
        let b = ((s.speed_rpm[i].max(0.0) / width).floor() as usize).min(nbins - 1);
        let (a, p) = (s.amplitude[i], s.phase_rad[i]);
        acc[b].0 += a;
        acc[b].1 += p.cos();
        acc[b].2 += p.sin();
        acc[b].3 += 1;
    }
    acc.into_iter().map(|(a, c, si, n)| (n > 0).then(|| (a / n as f64, si.atan2(c)))).collect()
}

/// `x` in the shorter of its plain and exponent forms (`6`, `1e300`), as a user writes it.
fn compact(x: f64) -> String {
    let (plain, exponent) = (format!("{x}"), format!("{x:e}"));
    if exponent.len() < plain.len() {
        exponent
    } else {
        plain
    }
}

/// Runs `orders`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.source.input.as_path()])?;
    let (t, fs) = a.source.read()?;
    let x = a.source.signal(&t)?;
    let speed = a.speed.rpm(&t, &a.source.input)?;
    if !(a.speed_bin.is_finite() && a.speed_bin > 0.0) {
        bail!("--speed-bin: must be positive, got {:?}", a.speed_bin);
    }
    crate::recording_args::speed_bins(&speed, a.speed_bin, &a.speed.speed, &a.source.input)?;
    if !(a.revs_per_block.is_finite() && a.revs_per_block >= 1.0) {
        bail!("--revs-per-block: must be at least 1 and finite, got {}", compact(a.revs_per_block));
    }
    let cfg = OrderSliceConfig { revs_per_block: a.revs_per_block, ..Default::default() };
    let mut slices = Vec::new();
    for &o in &a.orders {
        if !(o.is_finite() && o > 0.0) {
            bail!("--order: must be positive, got {}", compact(o));
        }
        let slice = order_slice(x, &speed, fs, o, &cfg).map_err(|e| anyhow::anyhow!("--order {}: {e}", compact(o)))?;
        slices.push(slice);
    }
    let nbins = crate::recording_args::speed_bins(&speed, a.speed_bin, &a.speed.speed, &a.source.input)?;
    let binned: Vec<_> = slices.iter().map(|s| bin(s, a.speed_bin, nbins)).collect();
    let mut header = vec!["speed rpm".to_string()];
    for o in &a.orders {
        header.push(format!("{o}× amplitude"));
        header.push(format!("{o}× phase °"));
    }
    let mut rows = Vec::new();
    for b in 0..nbins {
        if binned.iter().all(|v| v[b].is_none()) {
            continue;
        }
        let mut r = vec![format!("{:.0}–{:.0}", b as f64 * a.speed_bin, (b + 1) as f64 * a.speed_bin)];
        for v in &binned {
            match v[b] {
                Some((amp, ph)) => {
                    r.push(format!("{amp:.4e}"));
                    r.push(format!("{:+.1}", ph.to_degrees()));
                }
                None => {
                    r.push("—".into());
                    r.push("—".into());
                }
            }
        }
        rows.push(r);
    }
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut text = format!(
        "order slices of {} ({} revolutions per block; unit of {}):\n",
        a.source.signal, a.revs_per_block, a.source.signal
    );
    text += &text_table(&h, &rows);
    crate::stdout::print_report(&text, [Some(a.out.as_path())])?;
    let plot = LinePlot {
        title: format!("Order amplitudes of {} vs speed", a.source.signal),
        x_label: "speed (rpm)".into(),
        y_label: format!("amplitude ({})", a.source.signal),
        series: slices
            .iter()
            .map(|s| Series { name: format!("order {}", s.order), x: s.speed_rpm.clone(), y: s.amplitude.clone() })
            .collect(),
        log_y: true,
        ..Default::default()
    };
    strainwave_io::output::write_file(&a.out, plot.to_svg())?;
    Ok(())
}
