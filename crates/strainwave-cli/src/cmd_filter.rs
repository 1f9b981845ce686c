//! `strainwave filter`: the real-time ripple and misalignment canceller over a
//! recording, streaming in constant memory (or the offline smoother with `--smooth`).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use strainwave_core::ripple::{
    step, Order, PhaseSource, Reference, ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState,
};
use strainwave_io::{BoundChannel, RecordingReader, RecordingWriter};

use crate::filter_rows::RowCheck;
use crate::joint_config::{JointConfig, MAX_TABLE_LEN};

/// Columns the filter adds.
pub const OUTPUT_COLUMNS: &[&str] = &["torque", "ripple", "misalignment", "innovation", "nis", "filter_flags"];

/// Arguments of `filter`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Joint configuration (gear, channels, calibration, filter); see examples/joint-taghirad.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// Input recording (.csv, .parquet; `-` for CSV on standard input).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording: the input columns plus torque, ripple, misalignment, innovation, nis, filter_flags.
    #[arg(long)]
    pub out: PathBuf,
    /// Offline: forward filter plus Rauch–Tung–Striebel smoother (zero phase; reads the whole recording).
    #[arg(long)]
    pub smooth: bool,
    /// Commissioning: learn the ripple and misalignment coefficients over this run (the
    /// `full` model uses its learning tuning) and write them to FILE, for `filter.learned`.
    #[arg(long, value_name = "FILE", conflicts_with = "smooth")]
    pub learn: Option<PathBuf>,
    /// Prefix for the added columns (when the input already has a `torque` column).
    #[arg(long, default_value = "")]
    pub prefix: String,
    /// Go on over bad rows instead of stopping at the first: samples with a non-finite
    /// torque or angle are skipped by the canceller (flag bits 0-1 in filter_flags) and
    /// time that does not move forward restarts the phase; counts are reported at the end.
    #[arg(long)]
    pub lenient: bool,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The channels bound to the input's columns.
struct Bound {
    time: BoundChannel,
    torque: BoundChannel,
    motor_angle: Option<BoundChannel>,
    output_angle: Option<BoundChannel>,
    motor_velocity: Option<BoundChannel>,
    expected: Option<BoundChannel>,
}

fn bind(cfg: &JointConfig, r: &RecordingReader) -> Result<Bound> {
    let b = |c: &strainwave_io::Channel, key: &str| -> Result<BoundChannel> {
        let index = r.column_index(c.column_name()).map_err(|e| anyhow::anyhow!("{e} (channel `channels.{key}`)"))?;
        let (scale, offset) = c.scale_offset();
        if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
            bail!("`channels.{key}`: scale must be finite and non-zero, offset finite");
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
    fn check(&self, a: &Args, cfg: &JointConfig, columns: &[String]) -> RowCheck {
        let channels = [
            ("torque", Some(self.torque)),
            ("motor_angle", self.motor_angle),
            ("output_angle", self.output_angle),
            ("motor_velocity", self.motor_velocity),
            ("expected_torque", self.expected),
        ];
        RowCheck::new(&channels, self.time, columns, cfg.filter.sample_rate_hz, a.lenient, a.out.as_os_str() == "-")
    }
}

fn reference(name: &str) -> Result<Reference> {
    Ok(match name {
        "relative" => Reference::Relative,
        "output" => Reference::Output,
        "motor" => Reference::Motor,
        other => bail!("`filter.orders.reference` must be relative, output or motor, got `{other}`"),
    })
}

/// Runs `filter`.
pub fn run(a: &Args) -> Result<()> {
    let cfg = JointConfig::load(&a.config)?;
    let ctx = || format!("config {}", a.config.display());
    let fs = cfg.filter.sample_rate_hz;
    let phase = match cfg.filter.phase.as_str() {
        "angle" => PhaseSource::Angle,
        "velocity" => PhaseSource::Velocity,
        other => bail!("{}: `filter.phase` must be `angle` or `velocity`, got `{other}`", a.config.display()),
    };
    let core = |e: strainwave_core::Error| anyhow::anyhow!("{}: filter: {e}", a.config.display());
    match cfg.filter.model.as_str() {
        "full" => {
            let noise = cfg
                .filter
                .noise_nm
                .with_context(|| format!("{}: `filter.noise_nm` is needed by the full model", a.config.display()))?;
            // Learning (commissioning, or no learned file yet) or operating from learned priors.
            let m = match (&a.learn, &cfg.filter.learned) {
                (None, Some(_)) => RippleModel::<f64, 5>::full(fs, noise),
                _ => RippleModel::<f64, 5>::full_commissioning(fs, noise),
            }
            .map_err(core)?
            .with_phase_source(phase);
            if a.learn.is_none() && cfg.filter.learned.is_none() && !a.quiet {
                eprintln!(
                    "note: {}: no `filter.learned` file, so the full model learns from zero in this run; \
                     the misalignment needs several output revolutions (see `filter --learn`)",
                    a.config.display()
                );
            }
            stream(a, &cfg, &m)
        }
        "product" => {
            let noise = cfg
                .filter
                .noise_nm
                .with_context(|| format!("{}: `filter.noise_nm` is needed by the product model", a.config.display()))?;
            let m = RippleModel::<f64, 3>::product(fs, noise).map_err(core)?.with_phase_source(phase);
            stream(a, &cfg, &m)
        }
        "seed-4th-order" => {
            stream(a, &cfg, &RippleModel::<f64, 2>::seed_4th_order(fs).map_err(core)?.with_phase_source(phase))
        }
        "seed-6th-order" => {
            stream(a, &cfg, &RippleModel::<f64, 3>::seed_6th_order(fs).map_err(core)?.with_phase_source(phase))
        }
        "orders" => {
            let orders: Vec<Order<f64>> = cfg
                .filter
                .orders
                .iter()
                .map(|o| {
                    Order::new(reference(&o.reference)?, o.multiple)
                        .and_then(|x| x.with_noise(o.q_per_sample_nm2, o.q_per_rad_nm2))
                        .map_err(core)
                })
                .collect::<Result<_>>()
                .with_context(ctx)?;
            let r = cfg
                .filter
                .r_nm2
                .with_context(|| format!("{}: `filter.r_nm2` is needed by the orders model", a.config.display()))?;
            macro_rules! with_m {
                ($($m:literal)*) => {
                    match orders.len() {
                        $($m => {
                            let arr: [Order<f64>; $m] = orders.clone().try_into().map_err(|_| anyhow::anyhow!("orders"))?;
                            let mut model = RippleModel::new(arr, r, fs).map_err(core)?.with_phase_source(phase);
                            if let Some(q) = cfg.filter.bias_q_nm2 {
                                model = model.with_bias_state(q).map_err(core)?;
                            }
                            stream(a, &cfg, &model)
                        })*
                        n => bail!("{}: `filter.orders` needs 1 to 8 orders, got {n}", a.config.display()),
                    }
                };
            }
            with_m!(1 2 3 4 5 6 7 8)
        }
        other => bail!(
            "{}: `filter.model` must be full, product, seed-4th-order, seed-6th-order or orders, got `{other}`",
            a.config.display()
        ),
    }
}

fn stream<const M: usize>(a: &Args, cfg: &JointConfig, model: &RippleModel<f64, M>) -> Result<()> {
    let learned_model;
    let model = match (&cfg.filter.learned, &a.learn) {
        (Some(path), None) => {
            let field = || format!("{}: `filter.learned`", a.config.display());
            learned_model =
                crate::learned::LearnedFile::load(path).with_context(field)?.apply(*model, path).with_context(field)?;
            &learned_model
        }
        _ => model,
    };
    let gear = cfg.gear()?;
    let cal = cfg.calibration().with_context(|| a.config.display().to_string())?;
    let mut r = RecordingReader::open(&a.input)?;
    let ch = bind(cfg, &r)?;
    let velocity = model.phase_source() == PhaseSource::Velocity;
    if velocity && ch.motor_velocity.is_none() {
        bail!("{}: `filter.phase = \"velocity\"` needs `channels.motor_velocity`", a.config.display());
    }
    if !velocity && (ch.motor_angle.is_none() || ch.output_angle.is_none()) {
        bail!("{}: the angle phase needs `channels.motor_angle` and `channels.output_angle`", a.config.display());
    }
    let mut columns: Vec<String> = r.columns().to_vec();
    for c in OUTPUT_COLUMNS {
        let name = format!("{}{c}", a.prefix);
        if columns.contains(&name) {
            bail!("{}: already has a column `{name}`; choose --prefix", a.input.display());
        }
        columns.push(name);
    }
    let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
    let mut check = ch.check(a, cfg, r.columns());
    if a.smooth {
        return crate::cmd_filter_smooth::smooth(a, model, &mut r, &refs, &mut check, |row| {
            (inputs(&ch, &gear, &cal, row, velocity).0, ch.time.get(row))
        });
    }
    let mut w = RecordingWriter::create(&a.out, &refs)?;
    let mut state = RippleState::new(model);
    let mut row = Vec::with_capacity(columns.len());
    let mut last_t: Option<f64> = None;
    let mut first_t: Option<f64> = None;
    let mut extrapolated = 0u64;
    let progress = crate::progress::Progress::new("filter", a.quiet, None);
    while r.read_row(&mut row)? {
        let n = r.rows_read();
        check.row(&row, n, n - 1).with_context(|| a.input.display().to_string())?;
        let t = ch.time.get(&row);
        let (input, extra) = inputs(&ch, &gear, &cal, &row, velocity);
        extrapolated += u64::from(extra);
        let mut input = input;
        if let Some(t0) = last_t.filter(|t0| t.is_finite() && t > *t0) {
            input = input.with_dt(t - t0);
        }
        if t.is_finite() {
            first_t.get_or_insert(t);
            last_t = Some(t);
        }
        let o: RippleOutput<f64> = step(model, &mut state, &input)
            .map_err(|e| anyhow::anyhow!("{}: data row {n}: filter: {e}", a.input.display()))?;
        check.flags(o.flags, n);
        row.extend_from_slice(&[
            o.torque_nm,
            o.ripple_nm,
            o.misalignment_nm,
            o.innovation_nm,
            o.nis,
            o.flags.bits() as f64,
        ]);
        w.write_row(&row)?;
        if r.rows_read() % strainwave_io::DEFAULT_CHUNK_ROWS as u64 == 0 {
            if a.out.as_os_str() == "-" {
                w.flush()?;
            }
            progress.set(r.rows_read());
        }
    }
    progress.finish();
    if r.rows_read() == 0 {
        bail!("{}: no data rows", a.input.display());
    }
    let rows = w.finish()?;
    if let Some(path) = &a.learn {
        let file = crate::learned::LearnedFile::from_state(model, &state);
        file.save(path, &format!("learned by strainwave filter from {} ({rows} rows)", a.input.display()))?;
        if !a.quiet {
            eprintln!("learned coefficients -> {} (set `filter.learned` to use them)", path.display());
        }
    }
    if !a.quiet {
        eprintln!("filtered {rows} rows of {} -> {}", a.input.display(), a.out.display());
        if extrapolated > 0 {
            eprintln!("warning: {extrapolated} samples used the calibration outside its speed range (its extrapolation policy)");
        }
        let span = first_t.zip(last_t).map(|(t0, t1)| t1 - t0);
        for w in check.warnings(&a.input.display().to_string(), rows, span) {
            eprintln!("warning: {w}");
        }
    }
    Ok(())
}

/// The canceller's input for one row; `true` when the calibration extrapolated.
fn inputs(
    ch: &Bound,
    gear: &strainwave_core::gear::Gear<f64>,
    cal: &strainwave_core::calibration::Calibration<f64, MAX_TABLE_LEN>,
    row: &[f64],
    velocity: bool,
) -> (RippleInput<f64>, bool) {
    let speed = ch.motor_velocity.map_or(0.0, |c| c.get(row));
    let (torque, extrapolated) = match cal.apply_flagged(ch.torque.get(row), speed) {
        Ok(a) => (a.torque_nm, a.extrapolated),
        // A non-finite sample or a speed the policy rejects: the filter skips it.
        Err(_) => (f64::NAN, false),
    };
    let refs = if velocity {
        let w = speed;
        ReferenceValues::new(w * gear.relative_rate_rigid(1.0), gear.output_angle(w), w)
    } else {
        let (m, o) =
            (ch.motor_angle.map_or(f64::NAN, |c| c.get(row)), ch.output_angle.map_or(f64::NAN, |c| c.get(row)));
        ReferenceValues::from_gear(gear, m, o)
    };
    let mut input = RippleInput::new(torque, refs);
    if let Some(e) = ch.expected {
        input = input.with_expected_torque(e.get(row));
    }
    (input, extrapolated)
}
