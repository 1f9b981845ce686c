//! `estimate` as a job: link torque from the motor and link encoders with a model
//! written by `identify`, streamed row by row. When the model holds friction and rotor
//! inertia (identified against a motor-current torque), a `current_torque` column gives
//! the motor-current torque the model predicts, to check against a log that has only current.

use std::path::Path;

use anyhow::{bail, Context, Result};
use strainwave_analysis::ident::{FittedEstimator, KinematicFit, RateTracker};
use strainwave_core::torsion::{Estimate, EstimatorState};

use crate::identify::{refuse_count_scaling, ModelFile};
use crate::run::{RowSink, RowSource};
use crate::sample_clock::SampleClock;

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

/// Columns `estimate` adds (and `current_torque` after them when the model has friction).
pub const ESTIMATE_COLUMNS: &[&str] = &["torque", "torsion", "kinematic_error", "estimate_flags"];

/// Column added after [`ESTIMATE_COLUMNS`] when the model has friction.
pub const CURRENT_TORQUE_COLUMN: &str = "current_torque";

/// What a run of `estimate` counted.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct EstimateSummary {
    /// Rows written.
    pub rows: u64,
    /// Rows where a counter wrapped.
    pub wraps: u64,
    /// Rows with an encoder jump.
    pub jumps: u64,
    /// First data row (1-based) with a jump; 0 without one.
    pub first_jump: u64,
    /// Why the recording's rate was not checked (the model's time column is missing).
    pub unchecked_time: Option<String>,
}

impl EstimateSummary {
    /// The warnings, one a line: encoder jumps, a sample rate not checked.
    pub fn warning(&self) -> Option<String> {
        let jumps = (self.jumps > 0).then(|| {
            format!(
                "{} rows with encoder jumps (first at data row {}; estimate_flags 4/8): a counter wrapping that the model's encoders do not expect?",
                self.jumps, self.first_jump
            )
        });
        let lines: Vec<String> = jumps.into_iter().chain(self.unchecked_time.clone()).collect();
        (!lines.is_empty()).then(|| lines.join("\n"))
    }
}

/// A model file ready to run: its estimator built and checked.
pub struct Estimator {
    model: ModelFile,
    config: String,
    est: FittedEstimator<KinematicFit>,
}

impl Estimator {
    /// The model's time channel, if it names one.
    pub fn time_channel(&self) -> Option<&strainwave_io::Channel> {
        self.model.channels.time.as_ref()
    }

    /// Reads the model file `config` (written by `identify`) and builds its estimator;
    /// errors name the file.
    pub fn load(config: &Path) -> Result<Self> {
        let model = ModelFile::load(config)?;
        let est = Self::build(&model).with_context(|| format!("{}", config.display()))?;
        Ok(Self { model, config: config.display().to_string(), est })
    }

    /// The estimator of a model read from its file.
    fn build(model: &ModelFile) -> Result<FittedEstimator<KinematicFit>> {
        model.check_numbers()?;
        let gear = model.gear.gear()?;
        let kin = model.kinematic_fit()?;
        let fit = model.compliance_fit();
        let fs = model.sample_rate_hz;
        Ok(match &model.encoders {
            Some(enc) => {
                refuse_count_scaling(&model.channels.motor, "motor")?;
                refuse_count_scaling(&model.channels.link, "link")?;
                let (m, l) = enc.configs()?;
                fit.estimator_for_counts(gear, m, l, kin, fs)?
            }
            None => fit.estimator(gear, kin, fs)?,
        })
    }

    /// The model.
    pub fn model(&self) -> &ModelFile {
        &self.model
    }

    /// Runs the estimator over the rows of `source` (named `input` in messages), writing
    /// each row with the added columns to the sink `create` makes from the output's column
    /// names.
    pub fn run<S: RowSource, W: RowSink>(
        &self,
        source: &mut S,
        create: impl FnOnce(&[&str]) -> Result<W>,
        input: &str,
    ) -> Result<EstimateSummary> {
        let (model, est) = (&self.model, &self.est);
        let fs = model.sample_rate_hz;
        let index = |key: &str, ch: &strainwave_io::Channel, r: &S| -> Result<usize> {
            r.columns().iter().position(|c| c == ch.column_name()).with_context(|| {
                format!("{input}: missing encoder column `{}` (channels.{key} of {})", ch.column_name(), self.config)
            })
        };
        let mi = index("motor", &model.channels.motor, source)?;
        let li = index("link", &model.channels.link, source)?;
        let time = model.channels.time.as_ref();
        let mut clock = time.and_then(|t| SampleClock::find(t, source.columns(), fs));
        let unchecked_time = time.filter(|_| clock.is_none()).map(|t| {
            format!(
                "{input}: no time column `{}` (channels.time of {}): the recording's sample rate is not checked",
                t.column_name(),
                self.config
            )
        });
        let (ms, mo) = model.channels.motor.scale_offset();
        let (ls, lo) = model.channels.link.scale_offset();
        let mut rates = match &model.friction {
            Some(f) => {
                f.validate().with_context(|| format!("{}: friction", self.config))?;
                Some((*f, RateTracker::new(f.rate_span, fs)?))
            }
            None => None,
        };
        let mut added: Vec<&str> = ESTIMATE_COLUMNS.to_vec();
        if rates.is_some() {
            added.push(CURRENT_TORQUE_COLUMN);
        }
        let mut columns: Vec<&str> = source.columns().iter().map(String::as_str).collect();
        if let Some(c) = columns.iter().find(|c| added.contains(c)) {
            bail!("{input}: already has a column `{c}`");
        }
        columns.extend(added);
        let mut w = create(&columns)?;
        let mut st = EstimatorState::new();
        let mut row = Vec::new();
        let range = model.torque_range_nm;
        let (mut wraps, mut jumps, mut first_jump) = (0u64, 0u64, 0u64);
        let mut k = 0u64;
        while source.read_row(&mut row)? {
            k += 1;
            if let Some(c) = &mut clock {
                c.push(&row, input, |row| source.row_name(row))?;
            }
            let (m, l) = (row[mi], row[li]);
            let r = match &model.encoders {
                Some(_) => {
                    if !(m.is_finite() && l.is_finite() && m.fract() == 0.0 && l.fract() == 0.0) {
                        let at = source.row_name(&row);
                        bail!("{input}: {at}: encoder counts {m:?}, {l:?} are not whole numbers{}", counts_hint(input));
                    }
                    est.step_counts(&mut st, m as i64, l as i64)
                }
                None => {
                    if !(m.is_finite() && l.is_finite()) {
                        bail!("{input}: {}: encoder angles {m}, {l} are not finite", source.row_name(&row));
                    }
                    est.step_angles(&mut st, m * ms + mo, l * ls + lo)
                }
            };
            let e = r.map_err(|e| {
                let at = source.row_name(&row);
                anyhow::anyhow!("{input}: {at}: no torque within the model range ±{range:.1} N·m ({e})")
            })?;
            if e.link_torque_nm.is_nan() || e.link_torque_nm.abs() > range {
                bail!(
                    "{input}: {}: estimated torque {:.2} N·m is outside the model range ±{range:.1} N·m",
                    source.row_name(&row),
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
        if k == 0 {
            bail!("{input}: no data rows");
        }
        if let Some(c) = &clock {
            c.check_rate(input, &self.config)?;
        }
        let rows = w.finish()?;
        Ok(EstimateSummary { rows, wraps, jumps, first_jump, unchecked_time })
    }
}

/// Why counts of `input` may not be whole: an option interpolates between its rows.
pub(crate) fn counts_hint(input: &str) -> String {
    strainwave_io::interpolated_by(input).map_or(String::new(), |by| {
        format!(" ({by} interpolates between rows: read encoder counts without it, or map angles instead)")
    })
}
