//! Learning in operation (`strainwave filter --learn FILE`): beside the filter whose
//! output is written, a second canceller of the same joint runs **cold** (the model's
//! own priors, the `full` model in its commissioning tuning) over the same samples.
//! At the end of the run:
//!
//! - each order's evidence is its posterior without its cold prior (see
//!   [`crate::merge`]), merged by information into `FILE` when it exists (after
//!   checking that `FILE` belongs to this joint), else written as it is;
//! - an order analysis of the cold canceller's innovation ([`crate::discover`]) finds
//!   lines the model lacks; each significant one of at least [`MIN_AMPLITUDE_OF_NOISE`]
//!   times the noise is appended to the file's orders as a discovered order (up to
//!   [`MAX_ORDERS`] in all), and used as such by every later run;
//! - the file is written atomically (a temporary file, synced, renamed): an existing
//!   file is replaced only by its merged successor.
//!
//! The learning canceller starts cold whatever the config's `filter.learned` says, so
//! that what a run adds is its own data, never the file's coefficients counted again.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use strainwave_analysis::step_lock::StepLock;
use strainwave_core::ripple::{step, Order, Reference, RippleInput, RippleModel, RippleState, StepFlags};
use strainwave_io::output::AtomicFile;

use crate::canceller::{build_model_with, ModelVisitor, MAX_ORDERS};
use crate::config::JointConfig;
use crate::discover::{Discovery, OrderScan};
use crate::identity::{reference_name, JointIdentity};
use crate::learned::{LearnedFile, LearnedOrder};
use crate::merge::Gaussian2;

/// Share of a discovered line's amplitude taken as the 1σ of its coefficients on top of
/// the fit's own: the cold canceller's bias state and neighbouring orders take part of
/// a line, so the fit on its innovation is only a starting point for the canceller.
const DISCOVERED_MODEL_ERROR: f64 = 0.25;

/// Smallest amplitude of a discovered line worth an order, in units of the model's
/// measurement noise `√R`: a line of `0.3 √R` left out adds 2 % to the error's RMS.
/// Significant lines below it are reported, not added.
pub const MIN_AMPLITUDE_OF_NOISE: f64 = 0.3;

/// The header line of a learned file: the last recording learned from and its rows.
pub fn header(input: &str, rows: u64) -> String {
    format!("learned by strainwave, last from {input} ({rows} rows)")
}

/// One run's learning, whichever the model's order count.
pub trait RunLearner: Send + Sync {
    /// One sample, as the output filter got it.
    fn observe(&mut self, input: &RippleInput<f64>);
    /// The merged file and one line per discovery (and per line left out).
    fn finish(&self, target: Option<&LearnedFile>, path: &Path) -> Result<(LearnedFile, Vec<String>)>;
}

/// The learning side of a run: the cold canceller, the file it merges into.
pub struct Session {
    learner: Box<dyn RunLearner>,
    target: Option<LearnedFile>,
    path: PathBuf,
    /// Notes for the run's summary (a target without identity).
    pub notes: Vec<String>,
}

impl Session {
    /// Starts learning into `path` for `cfg`'s joint. An existing `path` of another
    /// joint is refused here, before anything runs.
    pub fn start(cfg: &JointConfig, path: &Path) -> Result<Self> {
        Self::begin(cfg, Some(path))
    }

    /// Starts learning for `cfg`'s joint with no file to merge into yet (the Python
    /// canceller's `learn=True`; see [`Self::merged`]).
    pub fn start_new(cfg: &JointConfig) -> Result<Self> {
        Self::begin(cfg, None)
    }

    fn begin(cfg: &JointConfig, into: Option<&Path>) -> Result<Self> {
        let mut notes = Vec::new();
        let path = into.unwrap_or(Path::new(""));
        let target = if into.is_some() && path.exists() {
            let (file, warning) = LearnedFile::load_for(path, cfg)?;
            notes.extend(warning);
            Some(file)
        } else {
            None
        };
        let extras = match &target {
            Some(t) => t.extras(path)?,
            None => Vec::new(),
        };
        let learner = build_model_with(cfg, false, &extras, MakeLearner { identity: JointIdentity::of(cfg)? })?;
        Ok(Self { learner, target, path: path.to_path_buf(), notes })
    }

    /// One sample.
    pub fn observe(&mut self, input: &RippleInput<f64>) {
        self.learner.observe(input);
    }

    /// The file learned so far merged into `target` (read from `path`; `None`: a new
    /// file), and the report lines, leaving the session going. [`Self::stage`] is this
    /// with the file the session started on.
    pub fn merged(&self, target: Option<&LearnedFile>, path: &Path) -> Result<(LearnedFile, Vec<String>)> {
        self.learner.finish(target, path)
    }

    /// The file as it was when the session started (`None`: none yet).
    pub fn target(&self) -> Option<&LearnedFile> {
        self.target.as_ref()
    }

    /// The file the session started on ([`Self::start`]), `None` for [`Self::start_new`].
    pub fn path(&self) -> Option<&Path> {
        (!self.path.as_os_str().is_empty()).then_some(self.path.as_path())
    }

    /// Merges the run into the file and stages it under a temporary name; it replaces
    /// the file on [`AtomicFile::commit`]. Returns the report lines too.
    pub fn stage(self, header: &str) -> Result<(AtomicFile, Vec<String>)> {
        let (file, mut lines) = self.learner.finish(self.target.as_ref(), &self.path)?;
        let staged = file.stage(&self.path, header)?;
        let mut notes = self.notes;
        notes.append(&mut lines);
        Ok((staged, notes))
    }
}

struct MakeLearner {
    identity: JointIdentity,
}

impl ModelVisitor for MakeLearner {
    type Output = Box<dyn RunLearner>;
    fn visit<const M: usize>(self, model: RippleModel<f64, M>) -> Result<Box<dyn RunLearner>> {
        let limits = model.limits();
        let scan =
            OrderScan::new(model.sample_rate_hz(), limits.nyquist_fraction, limits.hold_below_hz, model.phase_source());
        let lock = StepLock::new(model.sample_rate_hz());
        Ok(Box::new(Learner { state: RippleState::new(&model), model, scan, identity: self.identity, lock }))
    }
}

struct Learner<const M: usize> {
    model: RippleModel<f64, M>,
    state: RippleState<f64, M>,
    scan: OrderScan,
    identity: JointIdentity,
    lock: StepLock,
}

/// Posterior of order `i`: rotating-frame mean and 2×2 covariance from the state's
/// snapshot (means first, `2M` values and the bias, then the covariance blocks).
pub fn posterior<const M: usize>(state: &RippleState<f64, M>, i: usize) -> Option<Gaussian2> {
    let mut v = vec![0.0; RippleState::<f64, M>::SNAPSHOT_LEN];
    state.snapshot(&mut v).ok()?;
    let block = 2 * M + 1 + (i * M + i) * 4;
    let g = Gaussian2 {
        mean_nm: [*v.get(2 * i)?, *v.get(2 * i + 1)?],
        cov_nm2: [[*v.get(block)?, *v.get(block + 1)?], [*v.get(block + 2)?, *v.get(block + 3)?]],
    };
    // The layout check: the snapshot agrees with the state's own accessor.
    let (z, var) = state.learned(i)?;
    (z == g.mean_nm && var == g.cov_nm2[0][0].max(g.cov_nm2[1][1])).then_some(g)
}

impl<const M: usize> RunLearner for Learner<M> {
    fn observe(&mut self, input: &RippleInput<f64>) {
        // A covariance gone bad resets the learning state; the next samples start over.
        if let Ok(o) = step(&self.model, &mut self.state, input) {
            self.scan.observe(input, o.innovation_nm, o.flags);
            // Locked by its own load-step test: learning starts again (see `StepLock`).
            if self.lock.locked(o.flags.contains(StepFlags::LOAD_STEP)) {
                self.state.reset(&self.model);
            }
        }
    }

    fn finish(&self, target: Option<&LearnedFile>, path: &Path) -> Result<(LearnedFile, Vec<String>)> {
        let file = path.display().to_string();
        let velocity = self.model.phase_source() == strainwave_core::ripple::PhaseSource::Velocity;
        let (p0, _) = self.model.initial_variance_nm2();
        let mut orders: Vec<LearnedOrder> = Vec::with_capacity(M);
        let mut lines = Vec::new();
        let base_len = self.identity.orders.len();
        if let Some(t) = target {
            if t.orders.len() != M {
                bail!("{file}: has {} orders, this joint's model has {M}", t.orders.len());
            }
        }
        for (i, o) in self.model.orders().iter().enumerate() {
            let (mean, var) = o.prior();
            let prior = Gaussian2::isotropic(mean, var.unwrap_or(p0));
            let post = posterior(&self.state, i)
                .with_context(|| format!("{file}: the canceller's state does not read back (`orders[{i}]`)"))?;
            let evidence = Gaussian2::evidence(&post, &prior);
            let carries = !velocity && o.multiple().fract() == 0.0;
            let mut entry = match target.map(|t| &t.orders[i]) {
                Some(old) => {
                    let same = old.reference == crate::config::ReferenceChoice::from(o.reference())
                        && old.multiple == o.multiple()
                        && old.load_scaled == o.is_load_scaled();
                    if !same {
                        bail!("{file}: `orders[{i}]` is {}, this joint's model has {}", old.label(), label(o));
                    }
                    old.clone()
                }
                None => new_entry(o, &prior, i >= base_len),
            };
            let Some(e) = evidence else {
                let kept = if entry.runs == 0 { "its prior" } else { "the file's coefficients" };
                lines.push(format!("{}: nothing learned in this run (its line hardly moved); kept {kept}", label(o)));
                orders.push(entry);
                continue;
            };
            let merged = if !carries {
                // The phase restarts each run: keep only the size, as a zero-mean prior.
                let size = 0.5 * (e.mean_nm[0].powi(2) + e.mean_nm[1].powi(2)) + e.largest_variance_nm2();
                let v = if entry.runs == 0 { size } else { entry.variance_nm2.max(size) };
                Some(Gaussian2::isotropic([0.0; 2], v))
            } else if entry.runs == 0 {
                Some(e)
            } else {
                entry.gaussian().fuse(&e)
            };
            if let Some(g) = merged {
                entry.set_gaussian(&g);
                entry.runs = entry.runs.saturating_add(1);
            }
            orders.push(entry);
        }
        // Order analysis of the cold canceller's innovation.
        let modelled: Vec<(Reference, f64)> =
            self.model.orders().iter().map(|o| (o.reference(), o.multiple())).collect();
        let mut tested = 0;
        let found = self.scan.finish(&modelled, &mut tested);
        lines.push(format!(
            "order analysis of the innovation: {tested} candidate lines (0.5× to {}× of the relative, output and motor \
             angles), {} significant",
            crate::discover::MAX_MULTIPLE,
            found.len()
        ));
        for d in &found {
            let what = format!(
                "{} {}: {:.4} N·m, power {:.0}× the local median (threshold {:.1}×), {:.0} cycles",
                d.multiple,
                reference_name(d.reference),
                d.amplitude_nm(),
                d.power_ratio,
                d.threshold,
                d.cycles
            );
            let least = MIN_AMPLITUDE_OF_NOISE * self.model.noise_nm();
            if d.amplitude_nm() < least {
                lines.push(format!(
                    "found {what}; not added: below {least:.4} N·m ({MIN_AMPLITUDE_OF_NOISE} × the noise)"
                ));
                continue;
            }
            if orders.len() >= MAX_ORDERS {
                lines.push(format!("discovered {what}; not added: the model holds at most {MAX_ORDERS} orders"));
                continue;
            }
            orders.push(discovered_entry(&self.model, d));
            lines.push(format!("discovered {what}; added to {file}"));
        }
        Ok((LearnedFile { joint: Some(self.identity.clone()), orders }, lines))
    }
}

fn label(o: &Order<f64>) -> String {
    crate::identity::order_label(reference_name(o.reference()), o.multiple(), o.is_load_scaled())
}

/// A file entry that holds only the model's prior (no run has added to it yet).
fn new_entry(o: &Order<f64>, prior: &Gaussian2, discovered: bool) -> LearnedOrder {
    let mut entry = LearnedOrder {
        reference: o.reference().into(),
        multiple: o.multiple(),
        load_scaled: o.is_load_scaled(),
        cos_nm: 0.0,
        sin_nm: 0.0,
        variance_nm2: 1.0,
        covariance_nm2: None,
        runs: 0,
        discovered,
        q_per_sample_nm2: discovered.then_some(o.q_per_sample_nm2()),
        q_per_rad_nm2: discovered.then_some(o.q_per_rad_nm2()),
    };
    entry.set_gaussian(prior);
    entry
}

/// A discovered line as a file entry: its process noise is that of the model's first
/// order on the same reference that is not load-scaled (else of the first order), its
/// prior the fit widened by [`DISCOVERED_MODEL_ERROR`].
fn discovered_entry<const M: usize>(model: &RippleModel<f64, M>, d: &Discovery) -> LearnedOrder {
    let orders = model.orders();
    let template = orders
        .iter()
        .find(|o| o.reference() == d.reference && !o.is_load_scaled())
        .or_else(|| orders.iter().find(|o| o.reference().is_ripple() == d.reference.is_ripple() && !o.is_load_scaled()))
        .unwrap_or(&orders[0]);
    let widen = (DISCOVERED_MODEL_ERROR * d.amplitude_nm()).powi(2);
    let c = d.covariance_nm2;
    let g = if d.phase_carries {
        Gaussian2 { mean_nm: d.coefficients_nm, cov_nm2: [[c[0][0] + widen, c[0][1]], [c[1][0], c[1][1] + widen]] }
    } else {
        Gaussian2::isotropic([0.0; 2], 0.5 * d.amplitude_nm().powi(2) + widen)
    };
    let mut entry = LearnedOrder {
        reference: d.reference.into(),
        multiple: d.multiple,
        load_scaled: false,
        cos_nm: 0.0,
        sin_nm: 0.0,
        variance_nm2: 1.0,
        covariance_nm2: None,
        runs: 1,
        discovered: true,
        q_per_sample_nm2: Some(template.q_per_sample_nm2()),
        q_per_rad_nm2: Some(template.q_per_rad_nm2()),
    };
    entry.set_gaussian(&g);
    entry
}

#[cfg(test)]
mod tests {
    use super::*;
    use strainwave_core::ripple::ReferenceValues;

    /// The posterior read from the snapshot is the state's own: its mean and diagonal
    /// match `RippleState::learned`, and its covariance is symmetric positive definite.
    #[test]
    fn posterior_reads_the_state() {
        let model = RippleModel::<f64, 5>::full_commissioning(1000.0, 0.02).unwrap();
        let mut state = RippleState::new(&model);
        for k in 0..3000 {
            let m = 0.15 * k as f64;
            let phi = m * 1.01;
            let y = 1.0 + 0.3 * (2.0 * phi).sin() + 0.1 * (4.0 * phi + 1.0).cos() + 0.2 * (m / 100.0).sin();
            step(&model, &mut state, &RippleInput::new(y, ReferenceValues::new(phi, m / 100.0, m))).unwrap();
        }
        for i in 0..5 {
            let g = posterior(&state, i).unwrap();
            let (z, v) = state.learned(i).unwrap();
            assert_eq!(g.mean_nm, z);
            assert_eq!(g.cov_nm2[0][0].max(g.cov_nm2[1][1]), v);
            assert_eq!(g.cov_nm2[0][1], g.cov_nm2[1][0]);
            assert!(g.information().is_some(), "order {i}: {g:?}");
        }
        // The 2× line: 0.3 sin 2φ is the sin coefficient.
        let g = posterior(&state, 0).unwrap();
        assert!((g.mean_nm[1] - 0.3).abs() < 0.01 && g.mean_nm[0].abs() < 0.01, "{g:?}");
    }
}
