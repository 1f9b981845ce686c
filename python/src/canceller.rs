//! `RippleCanceller`: the joint config's canceller kept alive between calls, fed one
//! sample (`step`) or one block of arrays (`run`) at a time. The model is built by the
//! joint crate (`build_model`, with the learned coefficients), and each sample goes
//! through the channel scaling and the calibration as `strainwave filter` does it, so a
//! recording run block by block gives the command line's numbers bit for bit.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use strainwave_core::calibration::Calibration;
use strainwave_core::denoise::TorqueDenoiser;
use strainwave_core::gear::Gear;
use strainwave_core::ripple::{
    step, PhaseSource, ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState, StepFlags,
};
use strainwave_joint::canceller::{build_model, in_config_terms, ModelVisitor};
use strainwave_joint::config::ModelChoice;
use strainwave_joint::learned::LearnedOrder;
use strainwave_joint::{JointConfig, LearnedFile, MAX_TABLE_LEN};

use crate::columns::{to_numpy, Arrays};
use crate::error::to_py;

/// The model and its state, whatever the model's order count.
trait Stream: Send + Sync {
    fn step(&mut self, input: &RippleInput<f64>) -> Result<RippleOutput<f64>, strainwave_core::Error>;
    fn learned(&self) -> LearnedFile;
    fn reset(&mut self);
}

struct Held<const M: usize> {
    model: RippleModel<f64, M>,
    state: RippleState<f64, M>,
}

impl<const M: usize> Stream for Held<M> {
    fn step(&mut self, input: &RippleInput<f64>) -> Result<RippleOutput<f64>, strainwave_core::Error> {
        step(&self.model, &mut self.state, input)
    }
    fn learned(&self) -> LearnedFile {
        LearnedFile::from_state(&self.model, &self.state)
    }
    fn reset(&mut self) {
        self.state.reset(&self.model);
    }
}

/// Builds the model, applying the learned coefficients of `learned` when given.
struct Build<'a> {
    learned: Option<&'a Path>,
    config: &'a str,
}

impl ModelVisitor for Build<'_> {
    type Output = (Box<dyn Stream>, PhaseSource);
    fn visit<const M: usize>(self, model: RippleModel<f64, M>) -> Result<Self::Output> {
        let model = match self.learned {
            Some(path) => {
                let field = || format!("{}: `filter.learned`", self.config);
                LearnedFile::load(path).with_context(field)?.apply(model, path).with_context(field)?
            }
            None => model,
        };
        let phase = model.phase_source();
        Ok((Box::new(Held { state: RippleState::new(&model), model }), phase))
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

/// What one step gives: the canceller's outputs and the denoised torque (NaN without a
/// denoiser).
type StepOut = (RippleOutput<f64>, f64);

/// The canceller of a joint config, with state kept between calls. Not thread-safe
/// from Python: one canceller per stream.
#[pyclass(module = "strainwave._native")]
pub struct RippleCanceller {
    stream: Box<dyn Stream>,
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
    fn load(config: &Path, learned: Option<PathBuf>, learn: bool) -> Result<Self> {
        let cfg = JointConfig::load(config)?;
        let name = cfg.path.display().to_string();
        if learn && learned.is_some() {
            bail!("learned= and learn=True: learning starts from the model's commissioning tuning, without priors");
        }
        let learned = if learn { None } else { learned.or_else(|| cfg.filter.learned.clone()) };
        let (stream, phase) =
            build_model(&cfg, learned.is_some(), Build { learned: learned.as_deref(), config: &name })?;
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
        let o = self
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
            Some(d) => d.step(o.torque_nm, o.flags.contains(StepFlags::LOAD_STEP)),
            None => f64::NAN,
        };
        Ok((o, denoised))
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

/// What `run` returns: column names and arrays.
type Block<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>);

#[pymethods]
impl RippleCanceller {
    /// The canceller of the joint config at `config`. `learned`: a learned-coefficients
    /// file to start from instead of the config's `filter.learned`; `learn=True`: start
    /// from the commissioning tuning without priors, as `strainwave filter --learn` does.
    #[staticmethod]
    #[pyo3(signature = (config, learned=None, *, learn=false))]
    fn from_config(py: Python<'_>, config: PathBuf, learned: Option<PathBuf>, learn: bool) -> PyResult<Self> {
        py.detach(|| Self::load(&config, learned, learn)).map_err(to_py)
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
    ) -> PyResult<(f64, u16)> {
        let s = Sample { time, torque, motor_angle, output_angle, motor_velocity, expected_torque };
        let (o, _) = self.step_sample(s, &|n| format!("sample {n}")).map_err(to_py)?;
        Ok((o.torque_nm, o.flags.bits()))
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
                    let (o, d) = self.step_sample(s, &what)?;
                    let values =
                        [o.torque_nm, o.ripple_nm, o.misalignment_nm, o.innovation_nm, o.nis, o.flags.bits() as f64, d];
                    for (c, v) in out.iter_mut().zip(values) {
                        c.push(v);
                    }
                }
                Ok(out)
            })
            .map_err(to_py)?;
        Ok((out_names, to_numpy(py, data)))
    }

    /// The coefficients learned so far, one `(reference, multiple, load_scaled, cos_nm,
    /// sin_nm, variance_nm2)` per order (the learned file's entries).
    fn learned(&self) -> Vec<(String, f64, bool, f64, f64, f64)> {
        let f = self.stream.learned();
        f.orders
            .into_iter()
            .map(|o: LearnedOrder| (o.reference, o.multiple, o.load_scaled, o.cos_nm, o.sin_nm, o.variance_nm2))
            .collect()
    }

    /// Writes the learned coefficients as `strainwave filter --learn FILE` does.
    fn save_learned(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let file = self.stream.learned();
        let header = format!("learned by strainwave.RippleCanceller from {} samples", self.samples);
        py.detach(|| file.save(&path, &header)).map_err(to_py)
    }

    /// Back to the state of a new canceller (the learned priors kept).
    fn reset(&mut self) {
        self.stream.reset();
        if let Some(d) = self.denoiser.as_mut() {
            d.reset();
        }
        self.last_t = None;
        self.samples = 0;
        self.extrapolated = 0;
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
