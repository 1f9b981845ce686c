//! `RippleCanceller`: the joint config's canceller kept alive between calls, fed one
//! sample (`step`) or one block of arrays (`run`) at a time. The model, its learned file,
//! the canceller (under the do-no-harm guard unless `filter.guard = false`) and the
//! learning beside it are the joint crate's, built as `strainwave filter` builds them, and
//! each sample goes through the channel scaling and the calibration as `filter` does it,
//! so a recording run block by block gives the command line's numbers bit for bit.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use strainwave_core::calibration::Calibration;
use strainwave_core::denoise::TorqueDenoiser;
use strainwave_core::gear::Gear;
use strainwave_core::ripple::{PhaseSource, ReferenceValues, RippleInput, RippleModel, RippleOutput};
use strainwave_joint::canceller::{build_model_with, guarded_cold_start, in_config_terms, ModelVisitor};
use strainwave_joint::config::ModelChoice;
use strainwave_joint::health::Health;
use strainwave_joint::learn::Session;
use strainwave_joint::learned::LearnedOrder;
use strainwave_joint::run::{Canceller, OutputPrior};
use strainwave_joint::{JointConfig, LearnedFile, MAX_TABLE_LEN};

use crate::columns::{to_numpy, Arrays};
use crate::error::to_py;

/// The model and its canceller, whatever the model's order count.
trait Stream: Send + Sync {
    /// One sample: the output and its `filter_flags` bits.
    fn step(&mut self, input: &RippleInput<f64>) -> Result<(RippleOutput<f64>, u32), strainwave_core::Error>;
    /// The output canceller's coefficients now.
    fn coefficients(&self) -> LearnedFile;
    /// The guard's figures (`None` without the guard).
    fn health(&self) -> Option<Health>;
    fn reset(&mut self);
}

struct Held<const M: usize> {
    model: RippleModel<f64, M>,
    canceller: Canceller<M>,
    guard: bool,
    learned_prior: bool,
}

impl<const M: usize> Stream for Held<M> {
    fn step(&mut self, input: &RippleInput<f64>) -> Result<(RippleOutput<f64>, u32), strainwave_core::Error> {
        self.canceller.step(&self.model, input)
    }
    fn coefficients(&self) -> LearnedFile {
        LearnedFile::from_state(&self.model, self.canceller.state())
    }
    fn health(&self) -> Option<Health> {
        self.canceller.health(&self.model)
    }
    fn reset(&mut self) {
        self.canceller = Canceller::new(&self.model, self.guard, self.learned_prior);
    }
}

/// Builds the model with the learned file's priors, and its canceller as `filter` does.
struct Build<'a> {
    prior: Option<&'a OutputPrior>,
    cfg: &'a JointConfig,
    config: &'a str,
}

impl ModelVisitor for Build<'_> {
    type Output = (Box<dyn Stream>, PhaseSource);
    fn visit<const M: usize>(self, model: RippleModel<f64, M>) -> Result<Self::Output> {
        let model = match self.prior {
            Some(p) => p.file.apply(model, &p.path).with_context(|| format!("{}: `filter.learned`", self.config))?,
            // A cold `full` model under the guard starts as `filter`'s does.
            None => guarded_cold_start(self.cfg, model)?,
        };
        let phase = model.phase_source();
        let learned_prior = self.prior.is_some();
        let guard = self.cfg.filter.guard;
        let canceller = Canceller::new(&model, guard, learned_prior);
        Ok((Box::new(Held { model, canceller, guard, learned_prior }), phase))
    }
}

/// Learning beside the output, as `strainwave filter --learn FILE` does.
struct Learning {
    session: Session,
    /// The file it merges into by default (`learn=PATH`), `None` for `learn=True`.
    into: Option<PathBuf>,
}

impl Learning {
    fn start(cfg: &JointConfig, into: Option<PathBuf>) -> Result<Self> {
        let session = match &into {
            Some(p) => Session::start(cfg, p)?,
            None => Session::start_new(cfg)?,
        };
        Ok(Self { session, into })
    }
}

/// One channel's column and its scale and offset (into the config's units).
#[derive(Clone)]
struct Scaled {
    column: String,
    key: &'static str,
    scale: f64,
    offset: f64,
}

impl Scaled {
    fn of(c: &Option<strainwave_io::Channel>, key: &'static str, config: &str) -> Result<Option<Self>> {
        let Some(c) = c else { return Ok(None) };
        let (scale, offset) = c.scale_offset();
        if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
            bail!("{config}: `channels.{key}`: scale must be finite and non-zero, offset finite");
        }
        Ok(Some(Self { column: c.column_name().to_string(), key, scale, offset }))
    }
    fn get(&self, v: f64) -> f64 {
        v * self.scale + self.offset
    }
}

/// One sample's channels as the recording has them (before scaling); NaN when absent.
#[derive(Clone, Copy)]
struct Sample {
    time: f64,
    torque: f64,
    motor_angle: f64,
    output_angle: f64,
    motor_velocity: f64,
    expected_torque: Option<f64>,
}

/// What one step gives: the canceller's outputs, the `filter_flags` bits and the denoised
/// torque (NaN without a denoiser).
type StepOut = (RippleOutput<f64>, u32, f64);

/// The canceller of a joint config, with state kept between calls. Not thread-safe
/// from Python: one canceller per stream.
#[pyclass(module = "strainwave._native")]
pub struct RippleCanceller {
    stream: Box<dyn Stream>,
    cfg: JointConfig,
    learning: Option<Learning>,
    /// The recording last run (`run`'s `input_name`), for the learned file's header.
    last_input: String,
    config: String,
    orders_model: bool,
    sample_rate_hz: f64,
    gear: Gear<f64>,
    calibration: Calibration<f64, MAX_TABLE_LEN>,
    velocity: bool,
    time: Scaled,
    torque: Scaled,
    motor_angle: Option<Scaled>,
    output_angle: Option<Scaled>,
    motor_velocity: Option<Scaled>,
    expected_torque: Option<Scaled>,
    denoiser: Option<TorqueDenoiser<f64>>,
    last_t: Option<f64>,
    samples: u64,
    extrapolated: u64,
}

impl RippleCanceller {
    fn load(config: &Path, learned: Option<PathBuf>, learn: bool, learn_into: Option<PathBuf>) -> Result<Self> {
        let mut cfg = JointConfig::load(config)?;
        let name = cfg.path.display().to_string();
        let learn = learn || learn_into.is_some();
        // The output runs from the learned file as `filter` loads it; one named here must exist.
        let explicit = learned.is_some();
        if let Some(l) = learned {
            cfg.filter.learned = Some(l);
        }
        let prior = OutputPrior::load(&cfg, learn && !explicit)?;
        let extras = prior.as_ref().map(|p| p.extras.clone()).unwrap_or_default();
        let build = Build { prior: prior.as_ref(), cfg: &cfg, config: &name };
        let (stream, phase) = build_model_with(&cfg, prior.is_some(), &extras, build)?;
        let learning = if learn { Some(Learning::start(&cfg, learn_into)?) } else { None };
        let gear = cfg.gear().with_context(|| name.clone())?;
        let calibration = cfg.calibration().with_context(|| name.clone())?;
        let denoiser = cfg.denoiser().with_context(|| name.clone())?;
        let ch = &cfg.channels;
        let time = Scaled::of(&Some(ch.time.clone()), "time", &name)?.context("time")?;
        let torque = Scaled::of(&Some(ch.torque.clone()), "torque", &name)?.context("torque")?;
        let motor_angle = Scaled::of(&ch.motor_angle, "motor_angle", &name)?;
        let output_angle = Scaled::of(&ch.output_angle, "output_angle", &name)?;
        let motor_velocity = Scaled::of(&ch.motor_velocity, "motor_velocity", &name)?;
        let expected_torque = Scaled::of(&ch.expected_torque, "expected_torque", &name)?;
        let velocity = phase == PhaseSource::Velocity;
        if velocity && motor_velocity.is_none() {
            bail!("{name}: `filter.phase = \"velocity\"` needs `channels.motor_velocity`");
        }
        if !velocity && (motor_angle.is_none() || output_angle.is_none()) {
            bail!("{name}: the angle phase needs `channels.motor_angle` and `channels.output_angle`");
        }
        Ok(Self {
            stream,
            orders_model: cfg.filter.model == ModelChoice::Orders,
            sample_rate_hz: cfg.filter.sample_rate_hz,
            cfg,
            learning,
            last_input: "RippleCanceller.step".to_string(),
            config: name,
            gear,
            calibration,
            velocity,
            time,
            torque,
            motor_angle,
            output_angle,
            motor_velocity,
            expected_torque,
            denoiser,
            last_t: None,
            samples: 0,
            extrapolated: 0,
        })
    }

    /// One sample through the channel scaling, the calibration and the canceller (as
    /// `strainwave filter --lenient` steps a row). `what` names the sample in errors.
    fn step_sample(&mut self, s: Sample, what: &dyn Fn(u64) -> String) -> Result<StepOut> {
        self.samples += 1;
        let speed = self.motor_velocity.as_ref().map_or(0.0, |c| c.get(s.motor_velocity));
        let torque_nm = match self.calibration.apply_flagged(self.torque.get(s.torque), speed) {
            Ok(a) => {
                self.extrapolated += u64::from(a.extrapolated);
                a.torque_nm
            }
            // Not finite, made infinite, or a speed the calibration rejects: skipped.
            Err(_) => f64::NAN,
        };
        let refs = if self.velocity {
            ReferenceValues::new(speed * self.gear.relative_rate_rigid(1.0), self.gear.output_angle(speed), speed)
        } else {
            let m = self.motor_angle.as_ref().map_or(f64::NAN, |c| c.get(s.motor_angle));
            let o = self.output_angle.as_ref().map_or(f64::NAN, |c| c.get(s.output_angle));
            ReferenceValues::from_gear(&self.gear, m, o)
        };
        let mut input = RippleInput::new(torque_nm, refs);
        if let (Some(c), Some(e)) = (&self.expected_torque, s.expected_torque) {
            input = input.with_expected_torque(c.get(e));
        }
        let t = self.time.get(s.time);
        if let Some(t0) = self.last_t.filter(|t0| t.is_finite() && t > *t0) {
            input = input.with_dt(t - t0);
        }
        if t.is_finite() {
            self.last_t = Some(t);
        }
        let n = self.samples;
        if let Some(l) = self.learning.as_mut() {
            l.session.observe(&input);
        }
        let (o, bits) = self
            .stream
            .step(&input)
            .map_err(|e| anyhow!("{}: {}", what(n), in_config_terms(e, self.orders_model, self.sample_rate_hz)))?;
        let outputs = [o.torque_nm, o.ripple_nm, o.misalignment_nm, o.innovation_nm, o.nis];
        if let Some(v) = outputs.iter().find(|v| v.is_infinite()) {
            bail!(
                "{}: the filter's output overflows ({v}) from a torque of {torque_nm} N·m; \
                 check the calibration and `filter.noise_nm` in {}",
                what(n),
                self.config
            );
        }
        let denoised = match self.denoiser.as_mut() {
            Some(d) => d.step(o.torque_nm, o.flags),
            None => f64::NAN,
        };
        Ok((o, bits, denoised))
    }

    /// The file `save_learned` writes to `path` now (merged into it when `merge` and it
    /// exists), with the report lines.
    fn learned_file(&self, path: Option<&Path>, merge: bool) -> Result<(LearnedFile, Vec<String>)> {
        let Some(l) = &self.learning else {
            bail!(
                "{}: this canceller does not learn; start it with learn=True or learn=PATH \
                 (`filter --learn FILE`)",
                self.config
            )
        };
        let path = match path.or(l.into.as_deref()) {
            Some(p) => p,
            None => bail!("save_learned: no path (the canceller was started with learn=True)"),
        };
        let mut notes = Vec::new();
        let target = if merge && path.exists() {
            let (file, note) = LearnedFile::load_for(path, &self.cfg)?;
            notes.extend(note);
            Some(file)
        } else {
            None
        };
        let other_file = target.is_some() && l.into.as_deref() != Some(path);
        let (file, mut lines) = l.session.merged(target.as_ref(), path).map_err(|e| {
            // The learning canceller holds the discovered orders of the file it started on.
            if other_file {
                anyhow!(
                    "{} (to learn into it, start with learn=\"{}\")",
                    strainwave_joint::one_line(&e),
                    path.display()
                )
            } else {
                e
            }
        })?;
        notes.append(&mut lines);
        Ok((file, notes))
    }

    /// The names of the columns `run` returns.
    fn output_names(&self) -> Vec<String> {
        let mut names: Vec<String> = strainwave_joint::OUTPUT_COLUMNS.iter().map(|c| c.to_string()).collect();
        if self.denoiser.is_some() {
            names.push(strainwave_joint::DENOISED_COLUMN.to_string());
        }
        names
    }

    /// The channels `run` reads, with where each is among `names`.
    fn bind(&self, names: &[String], input: &str) -> Result<[Option<usize>; 6]> {
        let find = |c: &Option<Scaled>| -> Result<Option<usize>> {
            let Some(c) = c else { return Ok(None) };
            names.iter().position(|n| *n == c.column).map(Some).ok_or_else(|| {
                anyhow!(
                    "{input}: no column `{}` (columns: {}) (channel `channels.{}`)",
                    c.column,
                    names.join(", "),
                    c.key
                )
            })
        };
        Ok([
            find(&Some(self.time.clone()))?,
            find(&Some(self.torque.clone()))?,
            find(&self.motor_angle)?,
            find(&self.output_angle)?,
            find(&self.motor_velocity)?,
            find(&self.expected_torque)?,
        ])
    }
}

/// One learned order: `(reference, multiple, load_scaled, cos_nm, sin_nm, variance_nm2)`.
type Entry = (String, f64, bool, f64, f64, f64);

/// What `run` returns: column names and arrays.
type Block<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>);

#[pymethods]
impl RippleCanceller {
    /// The canceller of the joint config at `config`, under the do-no-harm guard unless
    /// the config sets `filter.guard = false`. `learned`: a learned-coefficients file to
    /// run from instead of the config's `filter.learned`. `learn=True`: a cold canceller
    /// learns beside the output, as `strainwave filter --learn` does; `learn_into`: the
    /// file it merges into (`--learn FILE`), checked now.
    #[staticmethod]
    #[pyo3(signature = (config, learned=None, *, learn=false, learn_into=None))]
    fn from_config(
        py: Python<'_>,
        config: PathBuf,
        learned: Option<PathBuf>,
        learn: bool,
        learn_into: Option<PathBuf>,
    ) -> PyResult<Self> {
        py.detach(|| Self::load(&config, learned, learn, learn_into)).map_err(to_py)
    }

    /// One sample, in the recording's units (the channels' scale and offset and the
    /// calibration are applied). Returns the clean torque (N·m) and the flags.
    #[pyo3(signature = (torque, motor_angle=f64::NAN, output_angle=f64::NAN, *, motor_velocity=f64::NAN, expected_torque=None, time=f64::NAN))]
    fn step(
        &mut self,
        torque: f64,
        motor_angle: f64,
        output_angle: f64,
        motor_velocity: f64,
        expected_torque: Option<f64>,
        time: f64,
    ) -> PyResult<(f64, u32)> {
        let s = Sample { time, torque, motor_angle, output_angle, motor_velocity, expected_torque };
        let (o, bits, _) = self.step_sample(s, &|n| format!("sample {n}")).map_err(to_py)?;
        Ok((o.torque_nm, bits))
    }

    /// A block of rows: `names` and their `arrays` (the config's channel columns), with the
    /// GIL released. Returns the added column names and arrays, as `filter` adds them.
    #[pyo3(signature = (names, arrays, *, input_name))]
    fn run_columns<'py>(
        &mut self,
        py: Python<'py>,
        names: Vec<String>,
        arrays: Vec<PyReadonlyArray1<'py, f64>>,
        input_name: String,
    ) -> PyResult<Block<'py>> {
        let arrays = Arrays::new(&names, arrays)?;
        let slices = arrays.slices();
        let rows = slices.first().map_or(0, |c| c.len());
        let out_names = self.output_names();
        let data = py
            .detach(|| -> Result<Vec<Vec<f64>>> {
                let [ti, qi, mi, oi, vi, ei] = self.bind(&names, &input_name)?;
                let col = |i: Option<usize>, k: usize| i.map_or(f64::NAN, |i| slices[i][k]);
                let first = self.samples;
                let mut out: Vec<Vec<f64>> = (0..out_names.len()).map(|_| Vec::with_capacity(rows)).collect();
                // Row `k` of several columns.
                #[allow(clippy::needless_range_loop)]
                for k in 0..rows {
                    let s = Sample {
                        time: col(ti, k),
                        torque: col(qi, k),
                        motor_angle: col(mi, k),
                        output_angle: col(oi, k),
                        motor_velocity: col(vi, k),
                        expected_torque: ei.map(|i| slices[i][k]),
                    };
                    let what = |n: u64| format!("{input_name}: data row {} (sample {n})", n - first);
                    let (o, bits, d) = self.step_sample(s, &what)?;
                    let values =
                        [o.torque_nm, o.ripple_nm, o.misalignment_nm, o.innovation_nm, o.nis, f64::from(bits), d];
                    for (c, v) in out.iter_mut().zip(values) {
                        c.push(v);
                    }
                }
                Ok(out)
            })
            .map_err(to_py)?;
        self.last_input = input_name;
        Ok((out_names, to_numpy(py, data)))
    }

    /// The learned file's entries, one `(reference, multiple, load_scaled, cos_nm,
    /// sin_nm, variance_nm2)` per order: when learning, the file `save_learned()` would
    /// write now (merged into the `learn_into` file as it was at the start); else the
    /// output canceller's coefficients.
    fn learned(&self, py: Python<'_>) -> PyResult<Vec<Entry>> {
        let file = py
            .detach(|| match &self.learning {
                Some(l) => {
                    let path = l.into.clone().unwrap_or_default();
                    l.session.merged(l.session.target(), &path).map(|(f, _)| f)
                }
                None => Ok(self.stream.coefficients()),
            })
            .map_err(to_py)?;
        Ok(file
            .orders
            .into_iter()
            .map(|o: LearnedOrder| {
                (o.reference.name().to_string(), o.multiple, o.load_scaled, o.cos_nm, o.sin_nm, o.variance_nm2)
            })
            .collect())
    }

    /// Writes what the learning canceller learned as `strainwave filter --learn FILE`
    /// does: merged by covariance into `path` when `merge` and it exists (after checking
    /// it is this joint's), written atomically. `path` defaults to `learn_into`. Returns
    /// the report lines (discovered orders, orders that learned nothing).
    #[pyo3(signature = (path=None, merge=true))]
    fn save_learned(&self, py: Python<'_>, path: Option<PathBuf>, merge: bool) -> PyResult<Vec<String>> {
        py.detach(|| -> Result<Vec<String>> {
            let (file, lines) = self.learned_file(path.as_deref(), merge)?;
            let path = path.as_deref().or(self.learning.as_ref().and_then(|l| l.into.as_deref())).context("path")?;
            // As `filter --learn`: never over the config or the calibration file it reads.
            let calibration = self.cfg.calibration.as_ref().and_then(|c| c.file.as_deref());
            strainwave_io::output::refuse_input_as_output(
                path,
                [self.cfg.path.as_path()].into_iter().chain(calibration),
            )?;
            let header = strainwave_joint::learn::header(&self.last_input, self.samples);
            file.stage(path, &header)?.commit()?;
            Ok(lines)
        })
        .map_err(to_py)
    }

    /// The do-no-harm guard's figures so far, as `filter` prints them at the end of a run:
    /// `None` when the config sets `filter.guard = false`.
    fn health<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(h) = self.stream.health() else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("samples", h.samples)?;
        d.set_item("mean_nis", h.mean_nis)?;
        d.set_item("expected_nis", 1.0)?;
        d.set_item("pass_through_share", h.pass_through_share)?;
        d.set_item("contradicted_share", h.contradicted_share)?;
        let orders: Vec<(String, f64)> = h.orders.iter().map(|o| (o.label.clone(), o.applied_share)).collect();
        d.set_item("applied_share", orders)?;
        d.set_item("warnings", h.warnings())?;
        d.set_item("lines", h.lines())?;
        Ok(Some(d))
    }

    /// Whether the do-no-harm guard runs (`filter.guard`).
    #[getter]
    fn guard(&self) -> bool {
        self.cfg.filter.guard
    }

    /// Whether a cold canceller learns beside the output.
    #[getter]
    fn learning(&self) -> bool {
        self.learning.is_some()
    }

    /// Back to the state of a new canceller (the learned priors kept; the learning starts
    /// over, from the `learn_into` file as it is now).
    fn reset(&mut self) -> PyResult<()> {
        if let Some(l) = &self.learning {
            self.learning = Some(Learning::start(&self.cfg, l.into.clone()).map_err(to_py)?);
        }
        self.last_input = "RippleCanceller.step".to_string();
        self.stream.reset();
        if let Some(d) = self.denoiser.as_mut() {
            d.reset();
        }
        self.last_t = None;
        self.samples = 0;
        self.extrapolated = 0;
        Ok(())
    }

    /// Samples stepped since the start or the last `reset`.
    #[getter]
    fn samples(&self) -> u64 {
        self.samples
    }

    /// Samples for which the calibration extrapolated its speed table.
    #[getter]
    fn extrapolated(&self) -> u64 {
        self.extrapolated
    }

    /// The config file's path as given.
    #[getter]
    fn config(&self) -> String {
        self.config.clone()
    }

    /// The column names `run` reads: `(time, torque, motor_angle, output_angle,
    /// motor_velocity, expected_torque)`, `None` for a channel the config does not have.
    #[getter]
    fn channel_columns(&self) -> Vec<Option<String>> {
        let c = |s: &Option<Scaled>| s.as_ref().map(|s| s.column.clone());
        vec![
            Some(self.time.column.clone()),
            Some(self.torque.column.clone()),
            c(&self.motor_angle),
            c(&self.output_angle),
            c(&self.motor_velocity),
            c(&self.expected_torque),
        ]
    }
}
