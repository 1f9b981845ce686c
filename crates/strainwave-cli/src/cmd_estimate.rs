//! `strainwave estimate`: link torque from the motor and link encoders with a model
//! written by `identify`, streamed row by row. When the model holds friction and rotor
//! inertia (identified against a motor-current torque), a `current_torque` column gives
//! the motor-current torque the model predicts, to check against a log that has only current.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use strainwave_analysis::ident::RateTracker;
use strainwave_core::torsion::{Estimate, EstimatorState};
use strainwave_io::{RecordingReader, RecordingWriter};

use crate::cmd_identify::{refuse_count_scaling, ModelFile};

/// Arguments of `estimate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model TOML written by `strainwave identify`.
    #[arg(long)]
    pub config: PathBuf,
    /// Input recording.
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording: the input columns plus torque, torsion, kinematic_error,
    /// estimate_flags (and current_torque when the model has friction).
    #[arg(long)]
    pub out: PathBuf,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Bits of the `estimate_flags` column.
pub mod flags {
    /// The motor counter rolled over (normal for a single-turn counter).
    pub const MOTOR_WRAPPED: u32 = 1;
    /// The link counter rolled over.
    pub const LINK_WRAPPED: u32 = 2;
    /// The motor count jumped by more than a quarter revolution: the angle may be wrong.
    pub const MOTOR_JUMP: u32 = 4;
    /// The link count jumped.
    pub const LINK_JUMP: u32 = 8;
}

fn flag_bits(e: &Estimate<f64>) -> u32 {
    let f = e.flags;
    let bit = |on: bool, b: u32| if on { b } else { 0 };
    bit(f.motor_wrapped, flags::MOTOR_WRAPPED)
        | bit(f.link_wrapped, flags::LINK_WRAPPED)
        | bit(f.motor_jump, flags::MOTOR_JUMP)
        | bit(f.link_jump, flags::LINK_JUMP)
}

/// Runs `estimate`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.input.as_path(), a.config.as_path()])?;
    let model = ModelFile::load(&a.config)?;
    let gear = model.gear.gear()?;
    let kin = model.kinematic_fit()?;
    let fit = model.compliance_fit();
    let fs = model.sample_rate_hz;
    let est = match &model.encoders {
        Some(enc) => {
            refuse_count_scaling(&model.channels.motor, "motor").with_context(|| format!("{}", a.config.display()))?;
            refuse_count_scaling(&model.channels.link, "link").with_context(|| format!("{}", a.config.display()))?;
            let (m, l) = enc.configs()?;
            fit.estimator_for_counts(gear, m, l, kin, fs)?
        }
        None => fit.estimator(gear, kin, fs)?,
    };
    let mut reader = RecordingReader::open(&a.input).with_context(|| format!("{}", a.input.display()))?;
    let index = |key: &str, ch: &strainwave_io::Channel, r: &RecordingReader| -> Result<usize> {
        r.columns().iter().position(|c| c == ch.column_name()).with_context(|| {
            format!(
                "{}: missing encoder column `{}` (channels.{key} of {})",
                a.input.display(),
                ch.column_name(),
                a.config.display()
            )
        })
    };
    let mi = index("motor", &model.channels.motor, &reader)?;
    let li = index("link", &model.channels.link, &reader)?;
    let (ms, mo) = model.channels.motor.scale_offset();
    let (ls, lo) = model.channels.link.scale_offset();
    let mut rates = match &model.friction {
        Some(f) => {
            f.validate().with_context(|| format!("{}: friction", a.config.display()))?;
            Some((*f, RateTracker::new(f.rate_span, fs)?))
        }
        None => None,
    };
    let added: &[&str] = if rates.is_some() {
        &["torque", "torsion", "kinematic_error", "estimate_flags", "current_torque"]
    } else {
        &["torque", "torsion", "kinematic_error", "estimate_flags"]
    };
    let mut columns: Vec<&str> = reader.columns().iter().map(String::as_str).collect();
    if let Some(c) = columns.iter().find(|c| added.contains(c)) {
        bail!("{}: already has a column `{c}`", a.input.display());
    }
    columns.extend(added);
    let columns: Vec<String> = columns.iter().map(|s| s.to_string()).collect();
    let names: Vec<&str> = columns.iter().map(String::as_str).collect();
    let mut w = RecordingWriter::create(&a.out, &names)?;
    let mut st = EstimatorState::new();
    let mut row = Vec::new();
    let range = model.torque_range_nm;
    let (mut wraps, mut jumps, mut first_jump) = (0u64, 0u64, 0u64);
    let mut k = 0u64;
    while reader.read_row(&mut row)? {
        k += 1;
        let (m, l) = (row[mi], row[li]);
        let r = match &model.encoders {
            Some(_) => {
                if !(m.is_finite() && l.is_finite() && m.fract() == 0.0 && l.fract() == 0.0) {
                    bail!("{}: data row {k}: encoder counts {m}, {l} are not whole numbers", a.input.display());
                }
                est.step_counts(&mut st, m as i64, l as i64)
            }
            None => {
                if !(m.is_finite() && l.is_finite()) {
                    bail!("{}: data row {k}: encoder angles {m}, {l} are not finite", a.input.display());
                }
                est.step_angles(&mut st, m * ms + mo, l * ls + lo)
            }
        };
        let e = r.map_err(|e| {
            anyhow::anyhow!(
                "{}: data row {k}: no torque within the model range ±{range:.1} N·m ({e})",
                a.input.display()
            )
        })?;
        if e.link_torque_nm.is_nan() || e.link_torque_nm.abs() > range {
            bail!(
                "{}: data row {k}: estimated torque {:.2} N·m is outside the model range ±{range:.1} N·m",
                a.input.display(),
                e.link_torque_nm
            );
        }
        let bits = flag_bits(&e);
        if bits & (flags::MOTOR_WRAPPED | flags::LINK_WRAPPED) != 0 {
            wraps += 1;
        }
        if bits & (flags::MOTOR_JUMP | flags::LINK_JUMP) != 0 {
            if jumps == 0 {
                first_jump = k;
            }
            jumps += 1;
        }
        row.extend_from_slice(&[e.link_torque_nm, e.torsion_rad, e.kinematic_error_rad, bits as f64]);
        if let Some((f, tracker)) = &mut rates {
            // The motor angle referred to the link: output angle less the torsion.
            let (v, acc) = tracker.step(e.output_angle_rad - e.torsion_rad);
            row.push(e.link_torque_nm + f.torque_nm(e.link_torque_nm, v, acc));
        }
        w.write_row(&row)?;
    }
    let rows = w.finish()?;
    if jumps > 0 {
        eprintln!(
            "warning: {jumps} rows with encoder jumps (first at data row {first_jump}; estimate_flags 4/8): a counter wrapping that the model's encoders do not expect?"
        );
    }
    if !a.quiet {
        eprintln!("estimated {rows} rows ({wraps} with counter wraps) -> {}", a.out.display());
    }
    Ok(())
}
