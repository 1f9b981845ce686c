//! The offline zero-phase smoother (forward filter plus
//! Rauch–Tung–Striebel pass) over a whole recording, in constant memory; with it the
//! smoothed torque (`torque_smoothed`, see `strainwave_analysis::smoother::torque`),
//! whose backward filter rides on the backward pass and forward filter on the last.
//!
//! Three passes: the forward filter reads the recording once, keeping its state every
//! [`BLOCK_ROWS`] rows and the rows themselves in scratch files; the backward pass
//! takes the blocks from the last to the first (each filtered again from its state) and
//! writes the smoothed values to another scratch file; the last pass writes the rows
//! with their smoothed values in order. The scratch files go beside the output (or in
//! the system's temporary folder when there is no output folder). On Unix they are unlinked as
//! soon as they are open, so nothing is left behind even if the run is killed;
//! elsewhere they are removed at the end, also on an error.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use strainwave_analysis::smoother::torque_ripple::{
    residual_orders, MeanSpeed, RippleTorqueEstimate, RippleTorqueTrack,
};
use strainwave_analysis::smoother::{CheckpointStore, CheckpointedSmoother, SmootherError};
use strainwave_core::denoise::TorqueDenoiser;
use strainwave_core::ripple::{ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState};

use crate::health::Health;
use crate::row_check::RowCheck;
use crate::run::{Canceller, FilterOptions, FilterSummary, RowSink, RowSource};

/// Rows per block of the backward pass. Memory: one block of the smoother's records
/// (about 2.3 kB per row for the full model, so about 10 MB), whatever the length; the
/// filter state at each block's start (about 1.3 kB) goes to a scratch file.
pub const BLOCK_ROWS: usize = 4096;

/// Values per row the smoother adds before the smoothed torque's backward prediction
/// (its state, covariance and noise share, [`RippleTorqueEstimate::values_len`] values): torque,
/// ripple, misalignment, innovation, nis, flags.
const ADDED: usize = 6;
/// The canceller's input as stored: torque, expected torque, three references, dt (NaN:
/// none); then the causal denoised torque of the forward pass (NaN: none); then the
/// guarded canceller's torque, ripple and misalignment, its `filter_flags` bits, and
/// whether the guard applied what the canceller would (1) or held some of it back (0).
const INPUT: usize = 12;

/// A scratch file of `f64` records of one width: unlinked once open (Unix), else
/// removed when dropped.
struct Scratch {
    path: PathBuf,
    file: File,
    width: usize,
}

impl Scratch {
    fn create(dir: &Path, tag: &str, width: usize) -> Result<Self> {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
        let path = dir.join(format!(".strainwave-smooth-{}-{nanos}-{tag}.tmp", std::process::id()));
        let mut options = File::options();
        options.read(true).write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let file = options
            .open(&path)
            .with_context(|| format!("{}: cannot create the smoother's scratch file", path.display()))?;
        // Open handles keep an unlinked file: nothing stays behind whatever ends the run.
        #[cfg(unix)]
        let _ = std::fs::remove_file(&path);
        Ok(Self { path, file, width })
    }

    fn context(&self) -> String {
        format!("{}: smoother scratch file", self.path.display())
    }

    /// Reads rows `first..first + rows` into `out` (flattened).
    fn read_rows(&mut self, first: usize, rows: usize, out: &mut Vec<f64>) -> Result<()> {
        let mut bytes = vec![0u8; rows * self.width * 8];
        self.file.seek(SeekFrom::Start((first * self.width * 8) as u64)).with_context(|| self.context())?;
        self.file.read_exact(&mut bytes).with_context(|| self.context())?;
        out.clear();
        out.extend(bytes.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8]))));
        Ok(())
    }

    /// Writes `values` (whole rows) from row `first` on.
    fn write_rows(&mut self, first: usize, values: &[f64]) -> Result<()> {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.file.seek(SeekFrom::Start((first * self.width * 8) as u64)).with_context(|| self.context())?;
        self.file.write_all(&bytes).with_context(|| self.context())
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        #[cfg(not(unix))]
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The smoother's block-start states, one snapshot per scratch-file row, so that its
/// memory does not grow with the recording.
struct ScratchStates<const M: usize> {
    model: RippleModel<f64, M>,
    file: Scratch,
    values: Vec<f64>,
}

impl<const M: usize> CheckpointStore<f64, M> for ScratchStates<M> {
    fn save(&mut self, block: usize, state: &RippleState<f64, M>) -> Result<(), String> {
        self.values.resize(RippleState::<f64, M>::SNAPSHOT_LEN, 0.0);
        state.snapshot(&mut self.values).map_err(|e| e.to_string())?;
        self.file.write_rows(block, &self.values).map_err(|e| format!("{e:#}"))
    }

    fn load(&mut self, block: usize) -> Result<RippleState<f64, M>, String> {
        self.file.read_rows(block, 1, &mut self.values).map_err(|e| format!("{e:#}"))?;
        RippleState::from_snapshot(&self.model, &self.values).map_err(|e| e.to_string())
    }
}

fn put(w: &mut impl Write, values: &[f64]) -> std::io::Result<()> {
    values.iter().try_for_each(|v| w.write_all(&v.to_le_bytes()))
}

fn get(r: &mut impl Read, values: &mut [f64]) -> std::io::Result<()> {
    let mut b = [0u8; 8];
    for v in values {
        r.read_exact(&mut b)?;
        *v = f64::from_le_bytes(b);
    }
    Ok(())
}

fn encode(
    i: &RippleInput<f64>,
    denoised_nm: f64,
    (guarded, bits): (&RippleOutput<f64>, u32),
    trusted: bool,
) -> [f64; INPUT] {
    let (r, g) = (i.references, guarded);
    let dt = i.dt_s.unwrap_or(f64::NAN);
    let trusted = f64::from(u8::from(trusted));
    let (torque, expected) = (i.torque_nm, i.expected_torque_nm);
    let (g_torque, g_ripple, g_mis) = (g.torque_nm, g.ripple_nm, g.misalignment_nm);
    let bits = f64::from(bits);
    [torque, expected, r.relative, r.output, r.motor, dt, denoised_nm, g_torque, g_ripple, g_mis, bits, trusted]
}

fn decode(v: &[f64]) -> RippleInput<f64> {
    let mut i = RippleInput::new(v[0], ReferenceValues::new(v[2], v[3], v[4])).with_expected_torque(v[1]);
    i.dt_s = (!v[5].is_nan()).then_some(v[5]);
    i
}

/// Runs the smoother over the whole recording and writes the smoothed columns (with
/// `denoiser`, the causal denoised torque of the forward pass before them).
///
/// Do no harm: `canceller` (guarded unless `filter.guard = false`, with the error
/// wording `in_config`) runs beside the smoother's forward pass. Where its guard holds
/// back any of what the canceller would cancel, the rows get the guard's causal torque,
/// ripple and misalignment, and that torque as `torque_smoothed` (its 1σ NaN): the
/// smoother's numbers stand only where the guard trusts the model. `filter_flags` are
/// the guarded canceller's, as without `--smooth`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn smooth<const M: usize, S: RowSource, W: RowSink>(
    opts: &FilterOptions,
    model: &RippleModel<f64, M>,
    (mut canceller, in_config): (Canceller<M>, &dyn Fn(strainwave_core::Error) -> String),
    mut denoiser: Option<TorqueDenoiser<f64>>,
    r: &mut S,
    mut w: W,
    check: &mut RowCheck,
    row_input: impl Fn(&[f64]) -> crate::run::RowInput,
) -> Result<FilterSummary> {
    let dir = opts.scratch_dir.clone().unwrap_or_else(std::env::temp_dir);
    let input = opts.input_name.as_str();
    let width = r.columns().len();
    // Samples count from 0, data rows from 1.
    let smoother_error = |e: SmootherError| match e {
        // In the config's words (the core names its internal parameters).
        SmootherError::Filter { index, source } => {
            anyhow!("{}: data row {}: {}", input, index + 1, crate::canceller::in_config_terms(source, false, f64::NAN))
        }
        SmootherError::NotPositiveDefinite { index } => anyhow!(
            "{}: data row {}: the smoother's uncertainty became invalid (a glitch in the torque or the angles, \
             or a `filter.noise_nm` far from the recording's noise?)",
            input,
            index + 1
        ),
        e => anyhow!("{}: smoother: {e}", input),
    };

    // Forward: filter, keep a state per block and the rows (both on disk).
    let mut rows = Scratch::create(&dir, "rows", width + INPUT)?;
    let mut spool = BufWriter::new(rows.file.try_clone().with_context(|| rows.context())?);
    let states = Scratch::create(&dir, "states", RippleState::<f64, M>::SNAPSHOT_LEN)?;
    let states = ScratchStates { model: *model, file: states, values: Vec::new() };
    let mut sm = CheckpointedSmoother::with_store(model, BLOCK_ROWS, states);
    // The mean relative speed decides which ripple orders the smoothed torque models.
    let mut speed = MeanSpeed::default();
    let mut row = Vec::new();
    let (mut first_t, mut last_t): (Option<f64>, Option<f64>) = (None, None);
    while r.read_row(&mut row)? {
        let name = |row: &[f64]| r.row_name(row);
        check.row(&row, 0, name).with_context(|| input.to_string())?;
        let crate::run::RowInput { mut sample, time_s: t, calibrated } = row_input(&row);
        if calibrated.overflow {
            check.calibration_overflow(&row, name).with_context(|| input.to_string())?;
        }
        if let Some(t0) = last_t.filter(|t0| t.is_finite() && t > *t0) {
            sample = sample.with_dt(t - t0);
        }
        if t.is_finite() {
            first_t.get_or_insert(t);
            last_t = Some(t);
        }
        speed.push(sample.references.relative);
        let o = sm.push(&sample).map_err(smoother_error)?;
        check.flags(o.flags, calibrated.rejected, &row, name);
        let (g, bits) =
            canceller.step(model, &sample).map_err(|e| anyhow!("{input}: {}: {}", name(&row), in_config(e)))?;
        // The guard applied the canceller's whole correction (same numbers to rounding);
        // a skipped sample (NaN torque) it does not judge, so the smoother fills it in.
        let held_back = (g.torque_nm - o.torque_nm).abs() > 1e-9 * (1.0 + sample.torque_nm.abs());
        let trusted = !held_back;
        let denoised = denoiser.as_mut().map_or(f64::NAN, |d| d.step(g.torque_nm, g.flags));
        put(&mut spool, &row)
            .and_then(|()| put(&mut spool, &encode(&sample, denoised, (&g, bits), trusted)))
            .with_context(|| rows.context())?;
    }
    spool.flush().with_context(|| rows.context())?;
    drop(spool);
    if sm.is_empty() {
        bail!("{input}: no data rows");
    }

    // Backward, block by block from the last.
    // The smoothed torque's two filters (level, rate and the residual ripple of the
    // canceller's relative-angle orders): backward here, forward in the last pass.
    let multiples = residual_orders(model, speed.rad_per_s(model.sample_rate_hz()));
    let (mut forward, mut backward) =
        RippleTorqueTrack::pair(multiples.len(), model.noise_nm(), model.sample_rate_hz());
    let n_state = forward.state_len();
    let state_values = RippleTorqueEstimate::values_len(n_state);
    let phasors = |relative_rad: f64| -> Vec<[f64; 2]> {
        multiples.iter().map(|n| [(n * relative_rad).cos(), (n * relative_rad).sin()]).collect()
    };
    let mut added = Scratch::create(&dir, "smoothed", ADDED + state_values)?;
    let (mut block, mut inputs, mut values) = (Vec::new(), Vec::new(), Vec::new());
    let mut predicted = Vec::new();
    for b in (0..sm.blocks()).rev() {
        let range = sm.block_range(b);
        rows.read_rows(range.start, range.len(), &mut block)?;
        inputs.clear();
        inputs.extend(block.chunks_exact(width + INPUT).map(|v| decode(&v[width..])));
        let s = sm.smooth_block(b, &inputs).map_err(smoother_error)?;
        predicted.clear();
        for (x, i) in s.smoothed.iter().zip(&inputs).rev() {
            let p = backward.predicted();
            // Restarted here: its prediction crossed a step and is dropped.
            let restarted = backward.push(x.torque_nm, &phasors(i.references.relative), false);
            predicted.push(if restarted { RippleTorqueEstimate::none(n_state) } else { p });
        }
        values.clear();
        for ((s, f), p) in s.smoothed.iter().zip(&s.filtered).zip(predicted.iter().rev()) {
            values.extend_from_slice(&[s.torque_nm, s.ripple_nm, s.misalignment_nm, f.innovation_nm, f.nis]);
            values.push(f.flags.bits() as f64);
            p.to_values(&mut values);
        }
        added.write_rows(range.start, &values)?;
    }

    // In order: the rows and their smoothed values.
    let rewind = |s: &mut Scratch| -> Result<BufReader<File>> {
        s.file.seek(SeekFrom::Start(0)).with_context(|| s.context())?;
        Ok(BufReader::new(s.file.try_clone().with_context(|| s.context())?))
    };
    let (mut rows_in, mut added_in) = (rewind(&mut rows)?, rewind(&mut added)?);
    let (mut line, mut extra) = (vec![0.0; width + INPUT], vec![0.0; ADDED + state_values]);
    for _ in 0..sm.len() {
        get(&mut rows_in, &mut line).with_context(|| rows.context())?;
        get(&mut added_in, &mut extra).with_context(|| added.context())?;
        // The stored input: torque, expected torque, relative angle, …, denoised torque,
        // the guarded outputs and whether the guard trusted the model.
        let stored = &line[width..];
        let (relative_rad, denoised) = (stored[2], stored[6]);
        let (guarded, trusted) = ([stored[7], stored[8], stored[9]], stored[11] == 1.0);
        let flags = stored[10];
        line.truncate(width);
        line.extend_from_slice(&extra[..ADDED]);
        // The flags of the run, the guard's included, as `filter` writes them.
        line[width + ADDED - 1] = flags;
        if !trusted {
            line[width..width + 3].copy_from_slice(&guarded);
        }
        if denoiser.is_some() {
            line.push(denoised);
        }
        forward.push(extra[0], &phasors(relative_rad), false);
        let back =
            RippleTorqueEstimate::from_values(n_state, &extra[ADDED..]).unwrap_or(RippleTorqueEstimate::none(n_state));
        let (t, sd) =
            forward.filtered().combine(back).map_or((extra[0], f64::NAN), |e| (e.level_nm(), e.level_sd_nm()));
        line.extend_from_slice(&if trusted { [t, sd] } else { [guarded[0], f64::NAN] });
        w.write_row(&line)?;
        line.resize(width + INPUT, 0.0);
    }
    let rows = w.finish()?;
    let span = first_t.zip(last_t).map(|(t0, t1)| t1 - t0);
    let health = canceller.health(model);
    let mut warnings = check.warnings(input, rows, span);
    warnings.extend(health.iter().flat_map(Health::warnings));
    Ok(FilterSummary { rows, notes: Vec::new(), extrapolated: 0, warnings, health })
}
