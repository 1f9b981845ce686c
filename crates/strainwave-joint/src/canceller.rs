//! The canceller model a joint config describes: `filter.model` (a preset or a list of
//! orders), the sample rate, the phase source and the bias state. `strainwave filter`
//! and the C model export (`strainwave export-c`) both build it here, so firmware runs
//! the model the command line runs.

use anyhow::{anyhow, bail, Context, Result};
use strainwave_core::guard::cold_start;
use strainwave_core::ripple::{Order, PhaseSource, RippleModel};

use crate::config::{JointConfig, ModelChoice, PhaseChoice};

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
    let phase = match cfg.filter.phase {
        PhaseChoice::Angle => PhaseSource::Angle,
        PhaseChoice::Velocity => PhaseSource::Velocity,
    };
    let orders_model = cfg.filter.model == ModelChoice::Orders;
    let core = |e: strainwave_core::Error| anyhow!("{config}: {}", in_config_terms(e, orders_model, fs));
    let noise = |model: &str| {
        cfg.filter.noise_nm.with_context(|| format!("{config}: `filter.noise_nm` is needed by the {model} model"))
    };
    match cfg.filter.model {
        ModelChoice::Full => {
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
        ModelChoice::Product => {
            let m = RippleModel::<f64, 3>::product(fs, noise("product")?).map_err(core)?.with_phase_source(phase);
            visitor.visit(m)
        }
        ModelChoice::Taghirad4thOrder => {
            let m = RippleModel::<f64, 2>::taghirad_4th_order(fs).map_err(core)?.with_phase_source(phase);
            visitor.visit(m)
        }
        ModelChoice::Taghirad6thOrder => {
            let m = RippleModel::<f64, 3>::taghirad_6th_order(fs).map_err(core)?.with_phase_source(phase);
            visitor.visit(m)
        }
        ModelChoice::Orders => {
            let orders: Vec<Order<f64>> = cfg
                .filter
                .orders
                .iter()
                .map(|o| -> Result<Order<f64>> {
                    Order::new(o.reference.into(), o.multiple)
                        .and_then(|x| x.with_noise(o.q_per_sample_nm2, o.q_per_rad_nm2))
                        .map_err(core)
                })
                .collect::<Result<_>>()?;
            let noise_nm = cfg.orders_noise_nm().with_context(|| config.clone())?;
            macro_rules! with_m {
                ($($m:literal)*) => {
                    match orders.len() {
                        $($m => {
                            let arr: [Order<f64>; $m] = orders.clone().try_into().map_err(|_| anyhow!("orders"))?;
                            let mut model = RippleModel::new(arr, noise_nm, fs).map_err(core)?.with_phase_source(phase);
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
    }
}

/// The model the do-no-harm guard runs when the `full` model learns from zero (no learned
/// file): its orders start at [`strainwave_core::guard::COLD_OSCILLATOR_VARIANCE_NM2`]
/// (see [`cold_start`]), so that a cold run reaches the noise floor. Other models, the
/// bare canceller (`filter.guard = false`) and the learner run the model as built.
pub fn guarded_cold_start<const M: usize>(
    cfg: &JointConfig,
    model: RippleModel<f64, M>,
) -> Result<RippleModel<f64, M>> {
    if !(cfg.filter.guard && cfg.filter.model == ModelChoice::Full) {
        return Ok(model);
    }
    let config = cfg.path.display().to_string();
    cold_start(model).map_err(|e| anyhow!("{config}: {}", in_config_terms(e, false, cfg.filter.sample_rate_hz)))
}

/// Largest number of orders a model holds: the config's plus the discovered ones (the
/// C ABI's `SW_MAX_ORDERS`, and the sizes the command line is built for).
pub const MAX_ORDERS: usize = 8;

/// [`build_model`], with `extra` orders (the ones a learned file discovered) appended
/// after the config's. Without extras the model is exactly [`build_model`]'s.
pub fn build_model_with<V: ModelVisitor>(
    cfg: &JointConfig,
    with_learned_priors: bool,
    extra: &[Order<f64>],
    visitor: V,
) -> Result<V::Output> {
    build_model(cfg, with_learned_priors, Extend { cfg, extra, visitor })
}

/// Appends orders to a built model, keeping its noise, bias, initial variances, phase
/// source and limits.
struct Extend<'a, V> {
    cfg: &'a JointConfig,
    extra: &'a [Order<f64>],
    visitor: V,
}

impl<V: ModelVisitor> ModelVisitor for Extend<'_, V> {
    type Output = V::Output;
    fn visit<const M: usize>(self, base: RippleModel<f64, M>) -> Result<V::Output> {
        if self.extra.is_empty() {
            return self.visitor.visit(base);
        }
        let config = self.cfg.path.display().to_string();
        let orders: Vec<Order<f64>> = base.orders().iter().chain(self.extra).copied().collect();
        let core = |e: strainwave_core::Error| {
            anyhow!("{config}: {}", in_config_terms(e, false, self.cfg.filter.sample_rate_hz))
        };
        let (p0_osc, p0_bias) = base.initial_variance_nm2();
        macro_rules! with_m {
            ($($m:literal)*) => {
                match orders.len() {
                    $($m => {
                        let arr: [Order<f64>; $m] = orders.clone().try_into().map_err(|_| anyhow!("orders"))?;
                        let mut model = RippleModel::new(arr, base.noise_nm(), base.sample_rate_hz())
                            .map_err(core)?
                            .with_phase_source(base.phase_source());
                        if let Some(q) = base.bias_q_nm2() {
                            model = model.with_bias_state(q).map_err(core)?;
                        }
                        let model = model
                            .with_initial_variance(p0_osc, p0_bias)
                            .and_then(|m| m.with_limits(*base.limits()))
                            .map_err(core)?;
                        self.visitor.visit(model)
                    })*
                    n => bail!("{config}: the model and the learned file's discovered orders make {n} orders, at most {MAX_ORDERS}"),
                }
            };
        }
        with_m!(1 2 3 4 5 6 7 8)
    }
}

/// A core error in the words of the config file: a parameter the user did not write
/// is named by the key it comes from (`filter.noise_nm`, also for the variance `r_nm2`
/// the tuning formulas make of it).
pub fn in_config_terms(e: strainwave_core::Error, orders_model: bool, sample_rate_hz: f64) -> String {
    use strainwave_core::Error as E;
    let key = |p: &'static str| match p {
        "noise_nm" | "r_nm2" => "filter.noise_nm",
        "sample_rate_hz" => "filter.sample_rate_hz",
        "q_per_sample_nm2" | "q_per_rad_nm2" | "multiple" if orders_model => p,
        "q_nm2" if orders_model => "filter.bias_q_nm2",
        // The presets' tuning makes the process noise of `noise_nm`.
        "q_per_sample_nm2" | "q_per_rad_nm2" | "q_nm2" => "filter.noise_nm",
        other => other,
    };
    match e {
        E::OutOfRange("bandwidth_hz") => {
            format!("`filter.sample_rate_hz` = {sample_rate_hz} is too low for the model's tracking bandwidth")
        }
        E::NotPositiveDefinite("ripple covariance") => "the filter's uncertainty became invalid (a glitch in the \
             torque or the angles, or a `filter.noise_nm` far from the recording's noise?)"
            .into(),
        E::NonPositive(p) => format!("`{}` must be positive", key(p)),
        E::NonFinite(p) => format!("`{}` must be finite", key(p)),
        E::OutOfRange(p) => format!("`{}` is out of range", key(p)),
        other => other.to_string(),
    }
}
