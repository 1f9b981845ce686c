//! The learned-coefficients file: what `strainwave filter --learn` writes at the end of
//! a commissioning run and `filter.learned` reads back as the canceller's priors.
//!
//! ```toml
//! # learned by strainwave filter from commissioning.csv (30400 rows)
//! [[orders]]
//! reference = "relative"   # relative | output | motor
//! multiple = 2.0
//! load_scaled = false
//! cos_nm = 0.2541          # contribution cos_nm cos(nθ) + sin_nm sin(nθ), θ the absolute angle
//! sin_nm = 0.4478          # (times |T̂| for a load-scaled order: N·m per N·m)
//! variance_nm2 = 1.3e-6
//! ```

use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use strainwave_core::ripple::{Reference, RippleModel, RippleState};
use strainwave_io::output::AtomicFile;

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearnedFile {
    /// One entry per order of the model, in the model's order.
    pub orders: Vec<LearnedOrder>,
}

/// One order's coefficients.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearnedOrder {
    /// `relative`, `output` or `motor`.
    pub reference: String,
    /// Multiple of the reference angle.
    pub multiple: f64,
    /// Whether the order is scaled by the load.
    pub load_scaled: bool,
    /// Coefficient of `cos(nθ)`, N·m (N·m per N·m when load-scaled).
    pub cos_nm: f64,
    /// Coefficient of `sin(nθ)`, N·m (N·m per N·m when load-scaled).
    pub sin_nm: f64,
    /// Variance of each coefficient, N·m².
    pub variance_nm2: f64,
}

fn reference_name(r: Reference) -> &'static str {
    match r {
        Reference::Relative => "relative",
        Reference::Output => "output",
        Reference::Motor => "motor",
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
                reference: reference_name(o.reference()).into(),
                multiple: o.multiple(),
                load_scaled: o.is_load_scaled(),
                cos_nm: z[0],
                sin_nm: z[1],
                variance_nm2: v,
            })
            .collect();
        Self { orders }
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

    /// Reads a file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        toml::from_str(&text).map_err(|e| {
            anyhow::anyhow!("{}: {}", path.display(), strainwave_analysis::calibration::toml_error_line(&text, &e))
        })
    }

    /// `model` with these coefficients as its priors; the orders must match one to one.
    pub fn apply<const M: usize>(&self, model: RippleModel<f64, M>, path: &Path) -> Result<RippleModel<f64, M>> {
        if self.orders.len() != M {
            bail!("{}: has {} orders, the model has {M}", path.display(), self.orders.len());
        }
        let mut priors = [([0.0; 2], 1.0); M];
        for (i, (o, l)) in model.orders().iter().zip(&self.orders).enumerate() {
            let same = l.reference == reference_name(o.reference())
                && l.multiple == o.multiple()
                && l.load_scaled == o.is_load_scaled();
            if !same {
                bail!(
                    "{}: `orders[{i}]` is {}× {}{}, the model's is {}× {}{}",
                    path.display(),
                    l.multiple,
                    l.reference,
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
        let four = RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap();
        assert!(file.apply(four, &path).unwrap_err().to_string().contains("has 5 orders"));
        std::fs::remove_file(&path).unwrap();
    }
}
