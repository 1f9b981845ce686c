//! The canceller model a joint config describes: `filter.model` (a preset or a list of
//! orders), the sample rate, the phase source and the bias state. `strainwave filter`
//! and the C model export (`strainwave export-c`) both build it here, so firmware runs
//! the model the command line runs.

use anyhow::{anyhow, bail, Context, Result};
use strainwave_core::ripple::{Order, PhaseSource, Reference, RippleModel};

use crate::config::JointConfig;

/// What to do with the model once built; the order count `M` is a compile-time size in
/// the core, so the caller gets the model through a generic method.
pub trait ModelVisitor {
    /// What the visit returns.
    type Output;
    /// Called once with the model.
    fn visit<const M: usize>(self, model: RippleModel<f64, M>) -> Result<Self::Output>;
}

/// Builds the model of `cfg` and hands it to `visitor`. `with_learned_priors`: the
/// learned coefficients will be applied (the `full` model then runs its operating tuning,
/// else its commissioning tuning, which learns from zero). Errors name the config file
/// and the key.
pub fn build_model<V: ModelVisitor>(cfg: &JointConfig, with_learned_priors: bool, visitor: V) -> Result<V::Output> {
    let fs = cfg.filter.sample_rate_hz;
    let config = cfg.path.display().to_string();
    let phase = match cfg.filter.phase.as_str() {
        "angle" => PhaseSource::Angle,
        "velocity" => PhaseSource::Velocity,
        other => bail!("{config}: `filter.phase` must be `angle` or `velocity`, got `{other}`"),
    };
    let core = |e: strainwave_core::Error| anyhow!("{config}: filter: {e}");
    let noise = |model: &str| {
        cfg.filter.noise_nm.with_context(|| format!("{config}: `filter.noise_nm` is needed by the {model} model"))
    };
    match cfg.filter.model.as_str() {
        "full" => {
            let noise = noise("full")?;
            let m = if with_learned_priors {
                RippleModel::<f64, 5>::full(fs, noise)
            } else {
                RippleModel::<f64, 5>::full_commissioning(fs, noise)
            }
            .map_err(core)?
            .with_phase_source(phase);
            visitor.visit(m)
        }
        "product" => {
            let m = RippleModel::<f64, 3>::product(fs, noise("product")?).map_err(core)?.with_phase_source(phase);
            visitor.visit(m)
        }
        "seed-4th-order" => {
            let m = RippleModel::<f64, 2>::seed_4th_order(fs).map_err(core)?.with_phase_source(phase);
            visitor.visit(m)
        }
        "seed-6th-order" => {
            let m = RippleModel::<f64, 3>::seed_6th_order(fs).map_err(core)?.with_phase_source(phase);
            visitor.visit(m)
        }
        "orders" => {
            let orders: Vec<Order<f64>> = cfg
                .filter
                .orders
                .iter()
                .map(|o| -> Result<Order<f64>> {
                    let reference = reference(&o.reference).with_context(|| format!("config {config}"))?;
                    Order::new(reference, o.multiple)
                        .and_then(|x| x.with_noise(o.q_per_sample_nm2, o.q_per_rad_nm2))
                        .map_err(core)
                })
                .collect::<Result<_>>()?;
            let r =
                cfg.filter.r_nm2.with_context(|| format!("{config}: `filter.r_nm2` is needed by the orders model"))?;
            macro_rules! with_m {
                ($($m:literal)*) => {
                    match orders.len() {
                        $($m => {
                            let arr: [Order<f64>; $m] = orders.clone().try_into().map_err(|_| anyhow!("orders"))?;
                            let mut model = RippleModel::new(arr, r, fs).map_err(core)?.with_phase_source(phase);
                            if let Some(q) = cfg.filter.bias_q_nm2 {
                                model = model.with_bias_state(q).map_err(core)?;
                            }
                            visitor.visit(model)
                        })*
                        n => bail!("{config}: `filter.orders` needs 1 to 8 orders, got {n}"),
                    }
                };
            }
            with_m!(1 2 3 4 5 6 7 8)
        }
        other => bail!(
            "{config}: `filter.model` must be full, product, seed-4th-order, seed-6th-order or orders, got `{other}`"
        ),
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
