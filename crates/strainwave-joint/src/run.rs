//! The canceller over a whole recording: the joint config's model (with its learned
//! coefficients), each row's channels through the calibration into the canceller, and the
//! canceller's outputs appended to the row. Streaming in constant memory; `smooth` runs the
//! offline smoother instead (see [`crate::smooth`]).
//!
//! The rows come from a [`RowSource`] and go to a [`RowSink`], so that a file, standard
//! input/output or a caller's arrays (Python) all give the same numbers.

use std::path::PathBuf;

use anyhow::{anyhow, bail, Context, Result};
use strainwave_core::guard::{Guard, GuardSettings};
use strainwave_core::ripple::{
    step, PhaseSource, ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState,
};
use strainwave_io::{BoundChannel, IoError, RecordingReader, RecordingWriter};

use crate::canceller::{build_model_with, guarded_cold_start, in_config_terms, ModelVisitor};
use crate::config::{JointConfig, ModelChoice, MAX_TABLE_LEN};
use crate::health::Health;
use crate::learned::LearnedFile;
use crate::row_check::RowCheck;

/// Columns the filter adds.
pub const OUTPUT_COLUMNS: &[&str] = &["torque", "ripple", "misalignment", "innovation", "nis", "filter_flags"];

/// Column added after [`OUTPUT_COLUMNS`] when `filter.torque_bandwidth_hz` is set: the
/// causal denoised torque (delayed by the denoiser's group delay).
pub const DENOISED_COLUMN: &str = "torque_denoised";

/// Columns `--smooth` adds after the others: the smoothed torque state and its 1σ.
pub const SMOOTHED_COLUMNS: &[&str] = &["torque_smoothed", "torque_smoothed_sd"];

/// Rows in: a recording's columns and its rows one at a time.
pub trait RowSource {
    /// Column names, in row order.
    fn columns(&self) -> &[String];
    /// Reads the next row into `row`; `false` at the end.
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError>;
    /// Data rows read so far.
    fn rows_read(&self) -> u64;
    /// How messages name `row`, the row last read (`data row N` unless the rows are not
    /// the input's, e.g. resampled).
    fn row_name(&self, _row: &[f64]) -> String {
        format!("data row {}", self.rows_read())
    }
}

/// Rows out.
pub trait RowSink {
    /// Appends one row.
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError>;
    /// Pushes buffered rows out (standard output, so that a reader sees them early).
    fn flush(&mut self) -> Result<(), IoError>;
    /// Completes the output; the number of rows written.
    fn finish(self) -> Result<u64, IoError>;
}

impl RowSource for RecordingReader {
    fn columns(&self) -> &[String] {
        RecordingReader::columns(self)
    }
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        RecordingReader::read_row(self, row)
    }
    fn rows_read(&self) -> u64 {
        RecordingReader::rows_read(self)
    }
    fn row_name(&self, row: &[f64]) -> String {
        RecordingReader::row_name(self, row)
    }
}

impl RowSink for RecordingWriter {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        RecordingWriter::write_row(self, row)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        RecordingWriter::flush(self)
    }
    fn finish(self) -> Result<u64, IoError> {
        RecordingWriter::finish(self)
    }
}

/// How to run the canceller over a recording.
#[derive(Debug, Clone, Default)]
pub struct FilterOptions {
    /// The input's name in messages (a path as the user wrote it, or `-`).
    pub input_name: String,
    /// Offline smoother (forward filter plus Rauch–Tung–Striebel pass) instead of the
    /// real-time filter.
    pub smooth: bool,
    /// Learn from this run, cold, beside the output filter, and merge what was learned
    /// into this file (see [`crate::learn`]).
    pub learn: Option<PathBuf>,
    /// Prefix of the added columns.
    pub prefix: String,
    /// Go on over bad rows (skipped by the canceller with a flag) instead of stopping.
    pub lenient: bool,
    /// The output is a stream seen as it is written (standard output): flushed by chunks,
    /// and errors say how much was already written.
    pub streaming_output: bool,
    /// Folder for the smoother's scratch files (beside the output); `None`: the system's
    /// temporary folder.
    pub scratch_dir: Option<PathBuf>,
}

/// What a run did, for the caller to print.
#[derive(Debug, Clone, Default)]
pub struct FilterSummary {
    /// Data rows written.
    pub rows: u64,
    /// Remarks before the run (how the model starts).
    pub notes: Vec<String>,
    /// Samples that used the calibration outside its speed range.
    pub extrapolated: u64,
    /// Warnings: skipped samples, time axis, sample rate.
    pub warnings: Vec<String>,
    /// The do-no-harm guard's figures (`None`: guard off).
    pub health: Option<Health>,
}

/// Bits of `filter_flags` above the canceller's own ([`StepFlags`](strainwave_core::ripple::StepFlags), bits 0–7): the
/// guard's flags ([`strainwave_core::guard::GuardFlags`]) from this bit on.
pub const GUARD_FLAGS_SHIFT: u32 = 8;
/// Bit of `filter_flags` from which one bit per order says it was NOT applied.
pub const WITHHELD_ORDERS_SHIFT: u32 = 16;

/// The canceller of a run: bare, or under the do-no-harm guard (`filter.guard`). The
/// Python package's streaming canceller holds one too, so both run the same steps.
#[derive(Debug, Clone)]
pub enum Canceller<const M: usize> {
    /// The canceller alone (`filter.guard = false`).
    Bare(RippleState<f64, M>),
    /// The canceller under the do-no-harm guard.
    Guarded(Box<Guard<f64, M>>),
}

impl<const M: usize> Canceller<M> {
    /// The canceller `filter` runs for `model` (its learned priors applied): guarded when
    /// `guard` (`filter.guard`), the guard taking the learned file as evidence when the
    /// model runs from one (`learned_prior`).
    pub fn new(model: &RippleModel<f64, M>, guard: bool, learned_prior: bool) -> Self {
        if guard {
            Canceller::Guarded(Box::new(Guard::new(model, GuardSettings { learned_prior, ..GuardSettings::default() })))
        } else {
            Canceller::Bare(RippleState::new(model))
        }
    }

    /// The guard's figures so far (`None` for the bare canceller).
    pub fn health(&self, model: &RippleModel<f64, M>) -> Option<Health> {
        match self {
            Canceller::Guarded(g) => Some(Health::new(model.orders(), g.stats())),
            Canceller::Bare(_) => None,
        }
    }

    /// The canceller's state (the guarded canceller's inner one).
    pub fn state(&self) -> &RippleState<f64, M> {
        match self {
            Canceller::Bare(s) => s,
            Canceller::Guarded(g) => g.state(),
        }
    }

    /// One sample: the output and the `filter_flags` bits.
    pub fn step(
        &mut self,
        model: &RippleModel<f64, M>,
        input: &RippleInput<f64>,
    ) -> Result<(RippleOutput<f64>, u32), strainwave_core::Error> {
        match self {
            Canceller::Bare(state) => step(model, state, input).map(|o| (o, u32::from(o.flags.bits()))),
            Canceller::Guarded(g) => g.step(model, input).map(|o| {
                let bits = u32::from(o.output.flags.bits())
                    | (u32::from(o.flags.bits()) << GUARD_FLAGS_SHIFT)
                    | (u32::from(o.withheld_mask()) << WITHHELD_ORDERS_SHIFT);
                (o.output, bits)
            }),
        }
    }
}

/// Runs the canceller of `cfg` over `source`, writing each row with the added columns to
/// the sink that `create` makes from the output column names. `progress` is called with
/// the rows read every chunk.
pub fn filter_recording<S: RowSource, W: RowSink>(
    cfg: &JointConfig,
    source: &mut S,
    create: impl FnOnce(&[&str]) -> Result<W>,
    opts: &FilterOptions,
    progress: &mut dyn FnMut(u64),
) -> Result<FilterSummary> {
    let config = cfg.path.display().to_string();
    let mut notes = Vec::new();
    if cfg.filter.model == ModelChoice::Full && opts.learn.is_none() && cfg.filter.learned.is_none() {
        let guard = if cfg.filter.guard {
            "; the do-no-harm guard applies each order only once the data support it, else passes the raw torque"
        } else {
            ""
        };
        notes.push(format!(
            "{config}: no `filter.learned` file, so the full model learns from zero in this run; \
             the misalignment needs several output revolutions (see `filter --learn`){guard}"
        ));
    }
    // A channel the recording lacks is named as such, before the learned file's
    // identity check would report the config's channel as another joint's.
    bind(cfg, source.columns(), &opts.input_name)?;
    // Operating from learned priors when the config has them (a `--learn` run may
    // create the file the config names); learning runs beside it, cold (crate::learn).
    let learned = OutputPrior::load(cfg, opts.learn.is_some())?;
    notes.extend(learned.as_ref().and_then(|l| l.note.clone()));
    let session = opts.learn.as_deref().map(|p| crate::learn::Session::start(cfg, p)).transpose()?;
    let extras = learned.as_ref().map(|l| l.extras.clone()).unwrap_or_default();
    let learned = learned.as_ref().map(|l| (&l.file, l.path.as_path()));
    let run = Run { cfg, opts, source, create, progress, learned, session };
    let mut summary = build_model_with(cfg, learned.is_some(), &extras, run)?;
    summary.warnings.splice(0..0, cfg.warnings.iter().cloned());
    if let Some(d) = cfg.denoiser()? {
        notes.push(format!(
            "torque_denoised: {} Hz, group delay at DC {:.2} ms",
            cfg.filter.torque_bandwidth_hz.unwrap_or(f64::NAN),
            1e3 * d.group_delay_s()
        ));
    }
    notes.append(&mut summary.notes);
    summary.notes = notes;
    Ok(summary)
}

/// The learned file the output canceller runs from: the config's `filter.learned`.
#[derive(Debug, Clone)]
pub struct OutputPrior {
    /// The file, checked to belong to the config's joint.
    pub file: LearnedFile,
    /// Its discovered orders, appended to the config's
    /// ([`crate::canceller::build_model_with`]).
    pub extras: Vec<strainwave_core::ripple::Order<f64>>,
    /// Where it was read.
    pub path: PathBuf,
    /// A note for the run's summary (a file without a joint identity).
    pub note: Option<String>,
}

impl OutputPrior {
    /// The config's learned file as `filter` loads it: `None` when the config names none,
    /// or when a learning run (`learning`) is to create the file it names.
    pub fn load(cfg: &JointConfig, learning: bool) -> Result<Option<Self>> {
        let Some(path) = &cfg.filter.learned else { return Ok(None) };
        if learning && !path.exists() {
            return Ok(None);
        }
        // The config's own errors name the config alone, not as the learned file's.
        crate::identity::JointIdentity::of(cfg)?;
        let field = || format!("{}: `filter.learned`", cfg.path.display());
        let (file, note) = LearnedFile::load_for(path, cfg).with_context(field)?;
        let extras = file.extras(path).with_context(field)?;
        Ok(Some(Self { file, extras, path: path.clone(), note }))
    }
}

/// The channels bound to the input's columns.
pub(crate) struct Bound {
    pub(crate) time: BoundChannel,
    torque: BoundChannel,
    motor_angle: Option<BoundChannel>,
    output_angle: Option<BoundChannel>,
    motor_velocity: Option<BoundChannel>,
    expected: Option<BoundChannel>,
}

fn bind(cfg: &JointConfig, columns: &[String], input: &str) -> Result<Bound> {
    let b = |c: &strainwave_io::Channel, key: &str| -> Result<BoundChannel> {
        let name = c.column_name();
        let index = columns.iter().position(|x| x == name).ok_or_else(|| {
            anyhow!("{input}: no column `{name}` (columns: {}) (channel `channels.{key}`)", columns.join(", "))
        })?;
        let (scale, offset) = c.scale_offset();
        if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
            bail!("{}: `channels.{key}`: scale must be finite and non-zero, offset finite", cfg.path.display());
        }
        Ok(BoundChannel { index, scale, offset })
    };
    let opt = |c: &Option<strainwave_io::Channel>, key: &str| c.as_ref().map(|c| b(c, key)).transpose();
    let ch = &cfg.channels;
    Ok(Bound {
        time: b(&ch.time, "time")?,
        torque: b(&ch.torque, "torque")?,
        motor_angle: opt(&ch.motor_angle, "motor_angle")?,
        output_angle: opt(&ch.output_angle, "output_angle")?,
        motor_velocity: opt(&ch.motor_velocity, "motor_velocity")?,
        expected: opt(&ch.expected_torque, "expected_torque")?,
    })
}

impl Bound {
    /// The row check over every channel the canceller reads.
    fn check(&self, cfg: &JointConfig, opts: &FilterOptions, columns: &[String]) -> RowCheck {
        let channels = [
            ("torque", Some(self.torque)),
            ("motor_angle", self.motor_angle),
            ("output_angle", self.output_angle),
            ("motor_velocity", self.motor_velocity),
            ("expected_torque", self.expected),
        ];
        RowCheck::new(&channels, self.time, columns, cfg.filter.sample_rate_hz, opts.lenient, opts.streaming_output)
    }

    /// The canceller's input for one row, and what the calibration did to its reading.
    pub(crate) fn input(
        &self,
        gear: &strainwave_core::gear::Gear<f64>,
        cal: &strainwave_core::calibration::Calibration<f64, MAX_TABLE_LEN>,
        row: &[f64],
        velocity: bool,
    ) -> RowInput {
        use strainwave_core::Error as E;
        let speed = self.motor_velocity.map_or(0.0, |c| c.get(row));
        let mut calibrated = Calibrated::default();
        let torque = match cal.apply_flagged(self.torque.get(row), speed) {
            Ok(a) => {
                calibrated.extrapolated = a.extrapolated;
                a.torque_nm
            }
            // A finite reading the calibration makes infinite: as a NaN in the file.
            Err(E::NonFinite("torque_nm")) => {
                calibrated.overflow = true;
                f64::NAN
            }
            // A speed outside the range, under `extrapolation = "reject"`: skipped.
            Err(E::OutOfRange("speed_rad_s")) => {
                calibrated.rejected = true;
                f64::NAN
            }
            // A non-finite sample: the filter skips it.
            Err(_) => f64::NAN,
        };
        let refs = if velocity {
            let w = speed;
            ReferenceValues::new(w * gear.relative_rate_rigid(1.0), gear.output_angle(w), w)
        } else {
            let (m, o) =
                (self.motor_angle.map_or(f64::NAN, |c| c.get(row)), self.output_angle.map_or(f64::NAN, |c| c.get(row)));
            ReferenceValues::from_gear(gear, m, o)
        };
        let mut sample = RippleInput::new(torque, refs);
        if let Some(e) = self.expected {
            sample = sample.with_expected_torque(e.get(row));
        }
        RowInput { sample, time_s: self.time.get(row), calibrated }
    }
}

/// A row as the canceller takes it.
pub(crate) struct RowInput {
    pub(crate) sample: RippleInput<f64>,
    pub(crate) time_s: f64,
    pub(crate) calibrated: Calibrated,
}

/// What the calibration did to a row's reading: extrapolated it (outside its speed
/// range), overflowed (a finite reading made infinite), or rejected its speed
/// (`extrapolation = "reject"`).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Calibrated {
    pub(crate) extrapolated: bool,
    pub(crate) overflow: bool,
    pub(crate) rejected: bool,
}

/// One run's settings and ends, for whichever model size the config has.
struct Run<'a, S, C> {
    cfg: &'a JointConfig,
    opts: &'a FilterOptions,
    source: &'a mut S,
    create: C,
    progress: &'a mut dyn FnMut(u64),
    learned: Option<(&'a LearnedFile, &'a std::path::Path)>,
    session: Option<crate::learn::Session>,
}

impl<S: RowSource, W: RowSink, C: FnOnce(&[&str]) -> Result<W>> ModelVisitor for Run<'_, S, C> {
    type Output = FilterSummary;
    fn visit<const M: usize>(self, model: RippleModel<f64, M>) -> Result<FilterSummary> {
        self.stream(&model)
    }
}

impl<S: RowSource, W: RowSink, C: FnOnce(&[&str]) -> Result<W>> Run<'_, S, C> {
    fn stream<const M: usize>(self, model: &RippleModel<f64, M>) -> Result<FilterSummary> {
        let Run { cfg, opts, source: r, create, progress, learned, mut session } = self;
        let config = cfg.path.display().to_string();
        let input = opts.input_name.as_str();
        let model = &match learned {
            Some((file, path)) => file.apply(*model, path).with_context(|| format!("{config}: `filter.learned`"))?,
            None => guarded_cold_start(cfg, *model)?,
        };
        let gear = cfg.gear().with_context(|| config.clone())?;
        let cal = cfg.calibration().with_context(|| config.clone())?;
        let ch = bind(cfg, r.columns(), input)?;
        let velocity = model.phase_source() == PhaseSource::Velocity;
        if velocity && ch.motor_velocity.is_none() {
            bail!("{config}: `filter.phase = \"velocity\"` needs `channels.motor_velocity`");
        }
        if !velocity && (ch.motor_angle.is_none() || ch.output_angle.is_none()) {
            bail!("{config}: the angle phase needs `channels.motor_angle` and `channels.output_angle`");
        }
        let mut columns: Vec<String> = r.columns().to_vec();
        let denoiser = cfg.denoiser().with_context(|| config.clone())?;
        let mut added: Vec<&str> = OUTPUT_COLUMNS.to_vec();
        if denoiser.is_some() {
            added.push(DENOISED_COLUMN);
        }
        if opts.smooth {
            added.extend_from_slice(SMOOTHED_COLUMNS);
        }
        for c in added {
            let name = format!("{}{c}", opts.prefix);
            if columns.contains(&name) {
                bail!("{input}: already has a column `{name}`; choose --prefix");
            }
            columns.push(name);
        }
        let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
        let mut check = ch.check(cfg, opts, r.columns());
        // The output runs from the config's learned file whenever there is one (a `--learn`
        // run learns beside it), so that file is the guard's evidence.
        let mut canceller = Canceller::new(model, cfg.filter.guard, learned.is_some());
        if opts.smooth {
            let w = create(&refs)?;
            let in_config = |e| in_config_terms(e, cfg.filter.model == ModelChoice::Orders, cfg.filter.sample_rate_hz);
            return crate::smooth::smooth(opts, model, (canceller, &in_config), denoiser, r, w, &mut check, |row| {
                ch.input(&gear, &cal, row, velocity)
            });
        }
        let mut w = create(&refs)?;
        let mut denoiser = denoiser;
        let mut row = Vec::with_capacity(columns.len());
        let mut last_t: Option<f64> = None;
        let mut first_t: Option<f64> = None;
        let mut extrapolated = 0u64;
        while r.read_row(&mut row)? {
            let n = r.rows_read();
            let name = |row: &[f64]| r.row_name(row);
            check.row(&row, n - 1, name).with_context(|| input.to_string())?;
            let RowInput { mut sample, time_s: t, calibrated } = ch.input(&gear, &cal, &row, velocity);
            if calibrated.overflow {
                check.calibration_overflow(&row, name).with_context(|| input.to_string())?;
            }
            extrapolated += u64::from(calibrated.extrapolated);
            if let Some(t0) = last_t.filter(|t0| t.is_finite() && t > *t0) {
                sample = sample.with_dt(t - t0);
            }
            if t.is_finite() {
                first_t.get_or_insert(t);
                last_t = Some(t);
            }
            if let Some(l) = session.as_mut() {
                l.observe(&sample);
            }
            let (o, flag_bits) = canceller.step(model, &sample).map_err(|e| {
                let why = in_config_terms(e, cfg.filter.model == ModelChoice::Orders, cfg.filter.sample_rate_hz);
                anyhow!("{input}: {}: {why}", name(&row))
            })?;
            check.flags(o.flags, calibrated.rejected, &row, name);
            // NaN marks a skipped sample; an infinity is an overflow the filter made.
            let outputs = [o.torque_nm, o.ripple_nm, o.misalignment_nm, o.innovation_nm, o.nis];
            if let Some(v) = outputs.iter().find(|v| v.is_infinite()) {
                let coefficients =
                    learned.map_or(String::new(), |(_, p)| format!(", and the coefficients in {}", p.display()));
                bail!(
                    "{input}: {}: the filter's output overflows ({v}) from a torque of {:?} N·m; \
                     check the calibration and `filter.noise_nm` in {config}{coefficients}",
                    name(&row),
                    sample.torque_nm
                );
            }
            row.extend_from_slice(&[
                o.torque_nm,
                o.ripple_nm,
                o.misalignment_nm,
                o.innovation_nm,
                o.nis,
                f64::from(flag_bits),
            ]);
            if let Some(d) = denoiser.as_mut() {
                row.push(d.step(o.torque_nm, o.flags));
            }
            w.write_row(&row)?;
            if n.is_multiple_of(strainwave_io::DEFAULT_CHUNK_ROWS as u64) {
                if opts.streaming_output {
                    w.flush()?;
                }
                progress(n);
            }
        }
        if r.rows_read() == 0 {
            bail!("{input}: no data rows");
        }
        // The learned file is written and synced before the output replaces anything:
        // a `--learn` that cannot be written leaves `--out` as it was.
        let rows = r.rows_read();
        let learned = match session {
            Some(l) => Some(l.stage(&crate::learn::header(input, rows))?),
            None => None,
        };
        let rows = w.finish()?;
        let mut notes = Vec::new();
        if let Some((file, mut lines)) = learned {
            file.commit()?;
            notes.append(&mut lines);
        }
        let span = first_t.zip(last_t).map(|(t0, t1)| t1 - t0);
        let health = canceller.health(model);
        let mut warnings = check.warnings(input, rows, span);
        warnings.extend(health.iter().flat_map(Health::warnings));
        Ok(FilterSummary { rows, notes, extrapolated, warnings, health })
    }
}
