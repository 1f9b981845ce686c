//! `fuse` as a job: hybrid torque from a torsion shaft and two accelerometers, shared by
//! the command line and the Python package.
//!
//! `online-corrected` (the default) and `complementary` stream one sample at a time
//! (constant memory): the first corrects each path with the inverse of its bench model
//! inside a fourth-order complementary pair, the second is the plain HOKA filter.
//! `spectral` (the paper's post-processing) and `corrected` (each path corrected by an
//! FIR inverse of its modelled response) read the whole recording.

use std::path::Path;

use anyhow::{bail, Context, Result};
use strainwave_analysis::bench::{
    complementary, spectral_combination, to_complex, CorrectedFusion, CorrectionConfig, CrossoverBand,
};
use strainwave_core::fusion::{
    AccelerometerPair, ComplementaryFusion, FusionState, OnlineCorrectedFusion, OnlineFusionState,
};
use strainwave_io::Table;
use strainwave_joint::run::{RowSink, RowSource};

pub mod check;
mod config;
use check::{design_summary, Check};
pub use config::{BenchConfig, Columns, Model, MAX_FIR_TAPS};

/// The index of column `name` of `path`, which `key` (the config key or option that
/// names it) asked for.
fn column(cols: &[String], name: &str, key: &str, path: &str) -> Result<usize> {
    cols.iter()
        .position(|c| c == name)
        .with_context(|| format!("{path}: no column `{name}` ({key}); columns: {}", cols.join(", ")))
}

/// Rows at the start of a recording whose time steps give its sample rate.
const RATE_ROWS: usize = 65;

/// The sample rate from the median step of `times` (the first data rows of column `name`,
/// at most [`RATE_ROWS`]): one late or early sample does not move it.
fn rate_from_time(times: &[f64], name: &str, input: &str) -> Result<f64> {
    let mut steps = Vec::with_capacity(times.len());
    for (k, w) in times.windows(2).enumerate() {
        let dt = w[1] - w[0];
        if !(dt.is_finite() && dt > 0.0) {
            bail!("{input}: row {}, column `{name}`: time {:?} s does not come after {:?} s", k + 2, w[1], w[0]);
        }
        steps.push(dt);
    }
    steps.sort_by(f64::total_cmp);
    match steps.get(steps.len() / 2) {
        Some(dt) => Ok(1.0 / dt),
        None => bail!("{input}: needs at least 2 samples"),
    }
}

/// The sample rate `sample_rate_hz` gives, checked against the rate of the time column
/// `name` ([`rate_from_time`]): a rate off by more than a factor of 2 is a wrong rate or
/// unit (the filters would be designed for another rate), not jitter.
fn configured_rate(fs: f64, times: &[f64], name: &str, input: &str, config: &str) -> Result<f64> {
    let from_time = rate_from_time(times, name, input)?;
    if !(0.5..=2.0).contains(&(fs / from_time)) {
        bail!(
            "{config}: `sample_rate_hz` = {fs:?} Hz, but the median time step of {input}'s first {} rows \
             (`{name}`) gives {from_time:.1} Hz: fix the rate, or leave it out to take it from the time column",
            times.len()
        );
    }
    Ok(fs)
}

/// The fusion methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Streamed, each path corrected by its bench model (needs `[model]`).
    OnlineCorrected,
    /// Streamed, the plain complementary (HOKA) filter.
    Complementary,
    /// The paper's offline spectral combination.
    Spectral,
    /// Offline, FIR-corrected paths (needs `[model]`).
    Corrected,
}

/// The method names, as the command line takes them.
pub const METHODS: [&str; 4] = ["online-corrected", "complementary", "spectral", "corrected"];

impl std::str::FromStr for Method {
    type Err = String;

    /// The method called `name` (one of [`METHODS`]); the error lists them.
    fn from_str(name: &str) -> std::result::Result<Self, String> {
        Ok(match name {
            "online-corrected" => Method::OnlineCorrected,
            "complementary" => Method::Complementary,
            "spectral" => Method::Spectral,
            "corrected" => Method::Corrected,
            other => return Err(format!("`{other}` is not one of {}", METHODS.join(", "))),
        })
    }
}

impl Method {
    /// The method called `name` (one of [`METHODS`]); the error names the `method` key.
    pub fn parse(name: &str) -> Result<Self> {
        name.parse().map_err(|e| anyhow::anyhow!("method: {e}"))
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Method::OnlineCorrected => METHODS[0],
            Method::Complementary => METHODS[1],
            Method::Spectral => METHODS[2],
            Method::Corrected => METHODS[3],
        }
    }

    /// Whether it streams one sample at a time (else it reads the whole recording).
    pub fn streams(self) -> bool {
        matches!(self, Method::OnlineCorrected | Method::Complementary)
    }
}

/// A bench configuration and a method, checked and ready to run over recordings.
pub struct Fuse {
    cfg: BenchConfig,
    config: String,
    method: Method,
    pair: AccelerometerPair<f64>,
}

/// Where `fuse` says what it designed and measured (text blocks, each ending in a newline).
pub type Say<'a> = &'a mut dyn FnMut(&str) -> Result<()>;

impl Fuse {
    /// The configuration `cfg` read from `config` for `method`; errors name `config`.
    pub fn new(cfg: BenchConfig, config: &Path, method: Method) -> Result<Self> {
        let config = config.display().to_string();
        let pair = AccelerometerPair::new(cfg.radius_m, cfg.stator_inertia_kg_m2)
            .map_err(|e| anyhow::anyhow!("{config}: {e}"))?;
        if method == Method::OnlineCorrected {
            cfg.model(method.name(), &config)?;
        }
        Ok(Self { cfg, config, method, pair })
    }

    /// Fuses the rows of `source` (named `input` in messages): each row is written with
    /// `fused_torque` added to the sink `create` makes from the output's column names.
    /// With `reference` (a column name) the fused torque's flatness against it is measured
    /// and said through `say`, as is the online design's response. Returns the rows written.
    pub fn run<S: RowSource, W: RowSink>(
        &self,
        source: &mut S,
        create: impl FnOnce(&[&str]) -> Result<W>,
        input: &str,
        reference: Option<&str>,
        say: Say<'_>,
    ) -> Result<u64> {
        let job = Job { cfg: &self.cfg, config: &self.config, method: self.method, pair: &self.pair, input, reference };
        if self.method.streams() {
            job.stream(source, create, say)
        } else {
            let columns = source.columns().to_vec();
            let table = Table::collect(Path::new(input), &columns, |row| source.read_row(row))?;
            job.offline(&table, create, say)
        }
    }
}

/// One run's settings.
struct Job<'a> {
    cfg: &'a BenchConfig,
    config: &'a str,
    method: Method,
    pair: &'a AccelerometerPair<f64>,
    input: &'a str,
    reference: Option<&'a str>,
}

/// A streaming fusion and its state (one per run: the size difference does not matter).
#[allow(clippy::large_enum_variant)]
enum Online {
    Complementary(ComplementaryFusion<f64>, FusionState<f64>),
    Corrected(OnlineCorrectedFusion<f64>, OnlineFusionState<f64>),
}

impl Online {
    fn settle(&mut self, torsion_nm: f64, accel_nm: f64) {
        match self {
            Online::Complementary(f, s) => *s = f.settled_state(torsion_nm, accel_nm),
            Online::Corrected(f, s) => *s = f.settled_state(torsion_nm, accel_nm),
        }
    }

    fn step(&mut self, torsion_nm: f64, accel_nm: f64) -> f64 {
        match self {
            Online::Complementary(f, s) => f.step(s, torsion_nm, accel_nm),
            Online::Corrected(f, s) => f.step(s, torsion_nm, accel_nm),
        }
    }
}

/// Indices of torsion and accelerometer columns.
struct Idx {
    time: usize,
    torsion: usize,
    accel: Result<(usize, usize), usize>,
}

impl Idx {
    fn new(cfg: &BenchConfig, cols: &[String], path: &str) -> Result<Self> {
        let c = &cfg.channels;
        let accel = match (&c.accel_1, &c.accel_2, &c.accel_torque) {
            (Some(a1), Some(a2), _) => {
                Ok((column(cols, a1, "channels.accel_1", path)?, column(cols, a2, "channels.accel_2", path)?))
            }
            (_, _, Some(t)) => Err(column(cols, t, "channels.accel_torque", path)?),
            _ => unreachable!("checked on load"),
        };
        let time = column(cols, &c.time, "channels.time", path)?;
        Ok(Self { time, torsion: column(cols, &c.torsion, "channels.torsion", path)?, accel })
    }

    /// The first value of `row` beyond what any sensor gives (see [`MAX_ACCEL_M_S2`] and
    /// [`MAX_TORQUE_NM`]), as a message naming its column: one glitched sample would
    /// otherwise reach the whole fused output.
    fn implausible(&self, cfg: &BenchConfig, row: &[f64]) -> Option<String> {
        let c = &cfg.channels;
        let beyond = |v: f64, limit: f64| v.abs() > limit;
        if beyond(row[self.torsion], MAX_TORQUE_NM) {
            return Some(torque_beyond(&c.torsion, row[self.torsion]));
        }
        match (self.accel, &c.accel_1, &c.accel_2, &c.accel_torque) {
            (Ok((i, j)), Some(a1), Some(a2), _) => [(i, a1), (j, a2)].into_iter().find(|&(k, _)| beyond(row[k], MAX_ACCEL_M_S2)).map(|(k, name)| {
                format!(
                    "column `{name}`: {:e} m/s² is beyond any accelerometer (limit ±{MAX_ACCEL_M_S2:e} m/s², about 100,000 g)",
                    row[k]
                )
            }),
            (Err(k), _, _, Some(name)) => beyond(row[k], MAX_TORQUE_NM).then(|| torque_beyond(name, row[k])),
            _ => None,
        }
    }

    fn accel_torque(&self, pair: &AccelerometerPair<f64>, row: &[f64]) -> f64 {
        match self.accel {
            Ok((i, j)) => pair.torque_nm(row[i], row[j]),
            Err(k) => row[k],
        }
    }
}

/// An acceleration beyond this is refused, m/s²: about 100,000 g, beyond the range of
/// shock accelerometers.
pub const MAX_ACCEL_M_S2: f64 = 1e6;
/// A torque beyond this is refused, N·m: ten times the largest torque transducers.
pub const MAX_TORQUE_NM: f64 = 1e7;

fn torque_beyond(column: &str, v: f64) -> String {
    format!("column `{column}`: {v:e} N·m is beyond any torque transducer (limit ±{MAX_TORQUE_NM:e} N·m)")
}

/// The column `fuse` adds.
pub const FUSED_COLUMN: &str = "fused_torque";

fn output_columns<'a>(cols: &'a [String], input: &str) -> Result<Vec<&'a str>> {
    if cols.iter().any(|c| c == FUSED_COLUMN) {
        bail!("{input}: already has a `fused_torque` column (the output adds one)");
    }
    let mut out: Vec<&str> = cols.iter().map(String::as_str).collect();
    out.push(FUSED_COLUMN);
    Ok(out)
}

impl Job<'_> {
    fn stream<S: RowSource, W: RowSink>(
        &self,
        rdr: &mut S,
        create: impl FnOnce(&[&str]) -> Result<W>,
        say: Say<'_>,
    ) -> Result<u64> {
        let (cfg, pair, config, method) = (self.cfg, self.pair, self.config, self.method.name());
        let cols = rdr.columns().to_vec();
        let idx = Idx::new(cfg, &cols, self.input)?;
        let reference = self.reference.map(|r| column(&cols, r, "--reference", self.input)).transpose()?;
        // The first rows give the sample rate; they are held back and written first.
        let mut head: Vec<Vec<f64>> = Vec::with_capacity(RATE_ROWS);
        let mut row = Vec::with_capacity(cols.len());
        while head.len() < RATE_ROWS && rdr.read_row(&mut row)? {
            head.push(std::mem::take(&mut row));
        }
        if head.len() < 2 {
            bail!("{}: needs at least 2 samples", self.input);
        }
        let times: Vec<f64> = head.iter().map(|r| r[idx.time]).collect();
        let name = &cfg.channels.time;
        let (fs, fs_from) = match cfg.sample_rate_hz {
            Some(fs) => (configured_rate(fs, &times, name, self.input, config)?, "`sample_rate_hz`".to_string()),
            None => (
                rate_from_time(&times, name, self.input)?,
                format!("{}: the median step of rows 1–{}, column `{name}`", self.input, times.len()),
            ),
        };
        let mut fusion = if self.method == Method::OnlineCorrected {
            let f = cfg.model(method, config)?.online(cfg.stator_inertia_kg_m2, (fs, &fs_from), config)?;
            let paths = cfg.model(method, config)?.paths(cfg.stator_inertia_kg_m2, config)?;
            say(&design_summary(&f, paths).with_context(|| config.to_string())?)?;
            Online::Corrected(f, OnlineFusionState::default())
        } else {
            cfg.check_crossover(fs, config)?;
            let f = ComplementaryFusion::new(cfg.crossover_hz, fs, cfg.crossover_order())
                .map_err(|e| anyhow::anyhow!("{}: {e}", config))?;
            Online::Complementary(f, FusionState::default())
        };
        let mut wtr = create(&output_columns(&cols, self.input)?)?;
        let mut check = reference.map(|_| Check::new(fs));
        let mut out_row = Vec::with_capacity(cols.len() + 1);
        let mut last_t = f64::NEG_INFINITY;
        let mut emit = |row: &[f64], n: u64, wtr: &mut W| -> Result<()> {
            let input = self.input;
            let time = row[idx.time];
            let at = |plain: &str| strainwave_io::row_label(input, n, time, plain);
            if !(time.is_finite() && time > last_t) {
                bail!(
                    "{input}: {}, column `{}`: time {time:?} s does not come after {last_t:?} s",
                    at("row"),
                    cfg.channels.time
                );
            }
            last_t = time;
            if let Some(what) = idx.implausible(cfg, row) {
                bail!("{input}: {}, {what}", at("data row"));
            }
            let (t, acc) = (row[idx.torsion], idx.accel_torque(pair, row));
            if !(t.is_finite() && acc.is_finite()) {
                bail!(
                    "{input}: {}: `{}` or the accelerometer torque is not finite (torsion {t}, accelerometers {acc} N·m)",
                    at("data row"),
                    cfg.channels.torsion
                );
            }
            if n == 1 {
                fusion.settle(t, acc);
            }
            let y = fusion.step(t, acc);
            if !y.is_finite() {
                bail!(
                    "{input}: {}: the fused torque overflows ({y}); check the scale of the input columns",
                    at("data row")
                );
            }
            if let (Some(c), Some(r)) = (check.as_mut(), reference) {
                c.push(row[r], y);
            }
            out_row.clear();
            out_row.extend_from_slice(row);
            out_row.push(y);
            wtr.write_row(&out_row)?;
            Ok(())
        };
        for (k, r) in head.iter().enumerate() {
            emit(r, k as u64 + 1, &mut wtr)?;
        }
        while rdr.read_row(&mut row)? {
            emit(&row, rdr.rows_read(), &mut wtr)?;
        }
        let rows = wtr.finish()?;
        if let (Some(c), Some(r)) = (check, self.reference) {
            say(&c.summary(method, r))?;
        }
        Ok(rows)
    }

    fn offline<W: RowSink>(
        &self,
        table: &Table,
        create: impl FnOnce(&[&str]) -> Result<W>,
        say: Say<'_>,
    ) -> Result<u64> {
        let (cfg, pair, config, method) = (self.cfg, self.pair, self.config, self.method.name());
        let idx = Idx::new(cfg, &table.columns, self.input)?;
        let reference = self.reference.map(|r| column(&table.columns, r, "--reference", self.input)).transpose()?;
        let n = table.rows();
        if n < 2 {
            bail!("{}: needs at least 2 samples", self.input);
        }
        let time = &table.data[idx.time];
        if let Some(k) = (0..n).find(|&k| !(time[k].is_finite() && (k == 0 || time[k] > time[k - 1]))) {
            bail!(
                "{}: row {}, column `{}`: time {:?} s does not come after the row before",
                self.input,
                k + 1,
                cfg.channels.time,
                time[k]
            );
        }
        let (times, name) = (&table.data[idx.time][..n.min(RATE_ROWS)], &cfg.channels.time);
        let fs = match cfg.sample_rate_hz {
            Some(fs) => configured_rate(fs, times, name, self.input, config)?,
            None => rate_from_time(times, name, self.input)?,
        };
        cfg.check_crossover(fs, config)?;
        let mut row = vec![0.0; table.columns.len()];
        for k in 0..n {
            for (c, v) in row.iter_mut().zip(&table.data) {
                *c = v[k];
            }
            if let Some(what) = idx.implausible(cfg, &row) {
                bail!(
                    "{}: {}, {what}",
                    self.input,
                    strainwave_io::row_label(self.input, k as u64 + 1, time[k], "data row")
                );
            }
        }
        let torsion = &table.data[idx.torsion];
        let accel: Vec<f64> = (0..n)
            .map(|k| match idx.accel {
                Ok((i, j)) => pair.torque_nm(table.data[i][k], table.data[j][k]),
                Err(c) => table.data[c][k],
            })
            .collect();
        if let Some(k) = (0..n).find(|&k| !(torsion[k].is_finite() && accel[k].is_finite())) {
            bail!(
                "{}: {}: `{}` or the accelerometer torque is not finite (torsion {}, accelerometers {} N·m)",
                self.input,
                strainwave_io::row_label(self.input, k as u64 + 1, time[k], "row"),
                cfg.channels.torsion,
                torsion[k],
                accel[k]
            );
        }
        // Errors of the designs come from the config's numbers.
        let in_config = |e: strainwave_analysis::AnalysisError| anyhow::anyhow!("{}: {e}", config);
        let fused = match self.method {
            Method::Spectral => spectral_combination(torsion, &accel, fs, cfg.crossover_hz).map_err(in_config)?,
            Method::Corrected => {
                let m = cfg.model(method, config)?;
                let (ts, acc) = m.paths(cfg.stator_inertia_kg_m2, config)?;
                // Taps beyond the recording only add zeros; the bound keeps a typo from
                // sizing the design's FFT.
                // An even count is rounded up to the odd one above it.
                if !(2..=MAX_FIR_TAPS).contains(&m.fir_taps) || m.fir_taps > n {
                    bail!(
                        "{}: [model] fir_taps = {}: must be from 2 to {MAX_FIR_TAPS} and at most the recording's {n} rows",
                        config,
                        m.fir_taps
                    );
                }
                let mut cc = CorrectionConfig::new(m.fir_taps | 1);
                cc.band = CrossoverBand::new(0.8 * cfg.crossover_hz, 1.2 * cfg.crossover_hz).map_err(in_config)?;
                if cc.band.hi_hz >= fs / 2.0 {
                    bail!(
                        "{}: `crossover_hz` = {} Hz: the crossover band (±20 %) reaches the Nyquist frequency {} Hz",
                        config,
                        cfg.crossover_hz,
                        fs / 2.0
                    );
                }
                let f = CorrectedFusion::design(
                    |f| to_complex(ts.response(f)),
                    |f| to_complex(acc.torque_response(f)),
                    fs,
                    &cc,
                )
                .map_err(in_config)?;
                f.apply(torsion, &accel)?
            }
            _ => {
                let f = ComplementaryFusion::new(cfg.crossover_hz, fs, cfg.crossover_order())
                    .map_err(|e| anyhow::anyhow!("{}: {e}", config))?;
                complementary(torsion, &accel, &f)?
            }
        };
        if let Some(k) = fused.iter().position(|y| !y.is_finite()) {
            bail!(
                "{}: row {}: the fused torque is not finite (torsion {}, accelerometers {} N·m); \
                 fix the recording or the scale of its columns",
                self.input,
                k + 1,
                torsion[k],
                accel[k]
            );
        }
        let mut wtr = create(&output_columns(&table.columns, self.input)?)?;
        let mut row = vec![0.0; table.columns.len() + 1];
        for (k, y) in fused.iter().enumerate() {
            for (c, v) in row.iter_mut().zip(&table.data) {
                *c = v[k];
            }
            row[table.columns.len()] = *y;
            wtr.write_row(&row)?;
        }
        let rows = wtr.finish()?;
        if let (Some(r), Some(name)) = (reference, self.reference) {
            let mut c = Check::new(fs);
            for (x, y) in table.data[r].iter().zip(&fused) {
                c.push(*x, *y);
            }
            say(&c.summary(method, name))?;
        }
        Ok(rows)
    }
}
