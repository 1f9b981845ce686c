//! The learned-coefficients file: what `strainwave filter --learn` writes (merging each
//! run into it, see [`crate::learn`]) and `filter.learned` reads back as the canceller's
//! priors.
//!
//! ```toml
//! # learned by strainwave, last from run.csv (30400 rows)
//! [joint]                  # the joint it belongs to (crate::identity)
//! ratio = 100.0
//! fixed = "circular_spline"
//! phase = "angle"
//! orders = ["2 relative", "4 relative", "2 relative load-scaled", "4 relative load-scaled", "1 output"]
//! channels = ["torque = bridge_voltage", "motor_angle = motor_angle", "output_angle = output_angle"]
//! fingerprint = "5a7104d121e8638d"
//!
//! [[orders]]
//! reference = "relative"   # relative | output | motor
//! multiple = 2.0
//! load_scaled = false
//! cos_nm = 0.2541          # contribution cos_nm cos(nθ) + sin_nm sin(nθ), θ the absolute angle
//! sin_nm = 0.4478          # (times |T̂| for a load-scaled order: N·m per N·m)
//! variance_nm2 = 1.3e-6    # the prior variance: larger eigenvalue of the covariance
//! covariance_nm2 = [1.3e-6, 2e-9, 1.2e-6]   # [P00, P01, P11]
//! runs = 3                 # runs merged into it
//! ```
//!
//! Orders the order analysis discovered follow the config's, with `discovered = true` and
//! their process noise (`q_per_sample_nm2`, `q_per_rad_nm2`). Files of older versions,
//! without `[joint]`, `covariance_nm2` and `runs`, are read as one run each.

use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use strainwave_core::ripple::{Order, RippleModel, RippleState};
use strainwave_io::output::AtomicFile;

use crate::config::{JointConfig, ReferenceChoice};
use crate::identity::reference_name;
use crate::identity::JointIdentity;
use crate::merge::Gaussian2;

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearnedFile {
    /// The joint the coefficients belong to (absent in files of older versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<JointIdentity>,
    /// One entry per order of the model, in the model's order: the config's orders,
    /// then the orders the order analysis discovered.
    pub orders: Vec<LearnedOrder>,
}

/// One order's coefficients.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearnedOrder {
    /// `relative`, `output` or `motor`.
    pub reference: ReferenceChoice,
    /// Multiple of the reference angle.
    pub multiple: f64,
    /// Whether the order is scaled by the load.
    pub load_scaled: bool,
    /// Coefficient of `cos(nθ)`, N·m (N·m per N·m when load-scaled).
    pub cos_nm: f64,
    /// Coefficient of `sin(nθ)`, N·m (N·m per N·m when load-scaled).
    pub sin_nm: f64,
    /// Variance of each coefficient as the canceller's prior takes it: the larger
    /// eigenvalue of `covariance_nm2`, N·m².
    pub variance_nm2: f64,
    /// Covariance of `[cos_nm, sin_nm]` as `[P00, P01, P11]`, N·m² (absent: `variance_nm2`
    /// on each, uncorrelated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance_nm2: Option<[f64; 3]>,
    /// Runs that added evidence about this order (0: the model's own prior; absent, in
    /// files of older versions: 1, the commissioning run that wrote it).
    #[serde(default = "one_run")]
    pub runs: u32,
    /// Found by the order analysis of the innovation, not in the config.
    #[serde(default, skip_serializing_if = "is_false")]
    pub discovered: bool,
    /// Process noise of a discovered order per sample, N·m².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_per_sample_nm2: Option<f64>,
    /// Process noise of a discovered order per radian of its phase, N·m².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_per_rad_nm2: Option<f64>,
}

fn one_run() -> u32 {
    1
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl LearnedOrder {
    /// The coefficients and their covariance.
    pub fn gaussian(&self) -> Gaussian2 {
        let mean = [self.cos_nm, self.sin_nm];
        match self.covariance_nm2 {
            Some(p) => Gaussian2::from_packed(mean, p),
            None => Gaussian2::isotropic(mean, self.variance_nm2),
        }
    }

    /// Sets the coefficients and covariance (and `variance_nm2` from it).
    pub fn set_gaussian(&mut self, g: &Gaussian2) {
        self.cos_nm = g.mean_nm[0];
        self.sin_nm = g.mean_nm[1];
        self.variance_nm2 = g.largest_variance_nm2();
        self.covariance_nm2 = Some(g.packed_cov());
    }

    /// `2 relative`, `2 relative load-scaled`.
    pub fn label(&self) -> String {
        crate::identity::order_label(self.reference.name(), self.multiple, self.load_scaled)
    }
}

impl LearnedFile {
    /// What `state` has learned under `model`.
    pub fn from_state<const M: usize>(model: &RippleModel<f64, M>, state: &RippleState<f64, M>) -> Self {
        let orders = model
            .orders()
            .iter()
            .zip(state.learned_all())
            .map(|(o, (z, v))| LearnedOrder {
                reference: o.reference().into(),
                multiple: o.multiple(),
                load_scaled: o.is_load_scaled(),
                cos_nm: z[0],
                sin_nm: z[1],
                variance_nm2: v,
                covariance_nm2: None,
                runs: 1,
                discovered: false,
                q_per_sample_nm2: None,
                q_per_rad_nm2: None,
            })
            .collect();
        Self { joint: None, orders }
    }

    /// Writes the file under a temporary name and syncs it; it replaces `path` on
    /// [`AtomicFile::commit`], so a caller can fail before replacing any output.
    pub fn stage(&self, path: &Path, header: &str) -> Result<AtomicFile> {
        let text = format!("# {header}\n{}", toml::to_string(self).context("learned coefficients")?);
        let mut file = AtomicFile::create(path)?;
        file.write_all(text.as_bytes()).with_context(|| format!("{}", path.display()))?;
        file.sync()?;
        Ok(file)
    }

    /// Writes the file (atomically: a temporary file synced and renamed into place).
    pub fn save(&self, path: &Path, header: &str) -> Result<()> {
        Ok(self.stage(path, header)?.commit()?)
    }

    /// Reads a file and checks each order's values; errors name the file and the key.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let file: Self = toml::from_str(&text).map_err(|e| crate::toml_error::one_line(path, &text, &e))?;
        for (i, o) in file.orders.iter().enumerate() {
            let at = |key: &str| format!("{}: `orders[{i}].{key}`", path.display());
            if !(o.multiple.is_finite() && o.multiple > 0.0) {
                bail!("{} must be positive, got {}", at("multiple"), o.multiple);
            }
            if !(o.cos_nm.is_finite() && o.sin_nm.is_finite()) {
                bail!("{} and `sin_nm` must be finite", at("cos_nm"));
            }
            if !(o.variance_nm2.is_finite() && o.variance_nm2 > 0.0) {
                bail!("{} must be positive, got {}", at("variance_nm2"), o.variance_nm2);
            }
            if o.covariance_nm2.is_some() && o.gaussian().information().is_none() {
                bail!("{} is not a positive definite covariance", at("covariance_nm2"));
            }
            for (key, q) in [("q_per_sample_nm2", o.q_per_sample_nm2), ("q_per_rad_nm2", o.q_per_rad_nm2)] {
                if q.is_some_and(|q| !(q.is_finite() && q >= 0.0)) {
                    bail!("{} must be finite and not negative", at(key));
                }
            }
            if i > 0 && file.orders[i - 1].discovered && !o.discovered {
                bail!("{}: discovered orders come after the config's", at("discovered"));
            }
        }
        Ok(file)
    }

    /// Reads a file for the joint of `cfg`: a file of another joint is refused, naming
    /// what differs; a file without identity (older versions) is accepted with the
    /// warning returned.
    pub fn load_for(path: &Path, cfg: &JointConfig) -> Result<(Self, Option<String>)> {
        let file = Self::load(path)?;
        let here = JointIdentity::of(cfg)?;
        match &file.joint {
            Some(id) => {
                if let Some(d) = here.differences(id) {
                    bail!("{}: learned on another joint than {}: {d}", path.display(), cfg.path.display());
                }
                Ok((file, None))
            }
            None => Ok((
                file,
                Some(format!(
                    "{}: no joint identity (a learned file of an older version): used without checking that it \
                     belongs to {}",
                    path.display(),
                    cfg.path.display()
                )),
            )),
        }
    }

    /// The discovered orders, as canceller orders with their process noise (priors
    /// come with [`Self::apply`]).
    pub fn extras(&self, path: &Path) -> Result<Vec<Order<f64>>> {
        self.orders
            .iter()
            .enumerate()
            .filter(|(_, o)| o.discovered)
            .map(|(i, o)| {
                Order::new(o.reference.into(), o.multiple)
                    .and_then(|x| x.with_noise(o.q_per_sample_nm2.unwrap_or(0.0), o.q_per_rad_nm2.unwrap_or(0.0)))
                    .map_err(|e| anyhow::anyhow!("{}: `orders[{i}]`: {e}", path.display()))
            })
            .collect()
    }

    /// `model` with these coefficients as its priors; the orders must match one to one.
    pub fn apply<const M: usize>(&self, model: RippleModel<f64, M>, path: &Path) -> Result<RippleModel<f64, M>> {
        if self.orders.len() != M {
            bail!("{}: has {} orders, the model has {M}", path.display(), self.orders.len());
        }
        let mut priors = [([0.0; 2], 1.0); M];
        for (i, (o, l)) in model.orders().iter().zip(&self.orders).enumerate() {
            let same = l.reference == ReferenceChoice::from(o.reference())
                && l.multiple == o.multiple()
                && l.load_scaled == o.is_load_scaled();
            if !same {
                bail!(
                    "{}: `orders[{i}]` is {}× {}{}, the model's is {}× {}{}",
                    path.display(),
                    l.multiple,
                    l.reference.name(),
                    if l.load_scaled { " (load-scaled)" } else { "" },
                    o.multiple(),
                    reference_name(o.reference()),
                    if o.is_load_scaled() { " (load-scaled)" } else { "" },
                );
            }
            priors[i] = ([l.cos_nm, l.sin_nm], l.variance_nm2);
        }
        model.with_priors(priors).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_mismatch() {
        let model = RippleModel::<f64, 5>::full(1000.0, 0.02).unwrap();
        let state = RippleState::new(&model);
        let mut file = LearnedFile::from_state(&model, &state);
        file.orders[4].cos_nm = 0.5;
        let path = std::env::temp_dir().join(format!("strainwave-learned-{}.toml", std::process::id()));
        file.save(&path, "test").unwrap();
        let back = LearnedFile::load(&path).unwrap();
        assert_eq!(back, file);
        let m = back.apply(model, &path).unwrap();
        assert_eq!(m.orders()[4].prior().0, [0.5, 0.0]);

        let seed = RippleModel::<f64, 5>::full(1000.0, 0.02).unwrap();
        let mut wrong = file.clone();
        wrong.orders[2].load_scaled = false;
        let err = wrong.apply(seed, &path).unwrap_err().to_string();
        assert!(err.contains("orders[2]") && err.contains("load-scaled"), "{err}");
        let four = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
        assert!(file.apply(four, &path).unwrap_err().to_string().contains("has 5 orders"));
        std::fs::remove_file(&path).unwrap();
    }
}
