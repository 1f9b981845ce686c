//! Writes golden data for the filterpy comparison (`python/tests/test_ripple_filterpy.py`):
//! the measurements, the Φ sequence (phase increments), Q, and the core filter's
//! predictions, for the product model in f64 (hold and load-step detector off, so the
//! filter is exactly the textbook prediction-type Kalman filter of Taghirad and Bélanger, 1999).
//!
//! `cargo run -p strainwave-core --example ripple_golden -- OUT.csv`

use std::f64::consts::TAU;
use std::io::Write;

use strainwave_core::ripple::{step_traced, Limits, ReferenceValues, RippleInput, RippleModel, RippleState, StepTrace};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: ripple_golden OUT.csv")?;
    let limits = Limits { hold_below_hz: 0.0, load_step_nis: 0.0, ..Limits::default() };
    let model = RippleModel::<f64, 3>::product(1000.0, 0.05)?.with_limits(limits)?;
    let mut state = RippleState::new(&model);
    let mut trace = StepTrace::new();
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path)?);
    let (p0, p0b) = model.initial_variance_nm2();
    writeln!(
        file,
        "# orders=3 bias=1 r_nm2={:.17e} p0={:.17e} p0_bias={:.17e} inflation={:.17e}",
        // `r_nm2`: the filter's measurement variance R, as filterpy takes it.
        model.noise_nm() * model.noise_nm(),
        p0,
        p0b,
        model.limits().covariance_inflation
    )?;
    writeln!(file, "k,y,y_hat,s,inc0,inc1,inc2,q0,q1,q2,q_bias")?;
    let mut seed = 0x9E37_79B9_7F4A_7C15_u64;
    for k in 0..3000 {
        let t = k as f64 / 1000.0;
        // Speed 40 ± 94 rad/s (reverses), a load step, ripple, misalignment, noise.
        let motor = 40.0 * t + 30.0 * (TAU * 0.5 * t).sin();
        let (out, rel) = (-motor / 100.0, motor * 1.01);
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let noise = 0.05 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
        let load = if t < 1.0 { 5.0 } else { -12.0 };
        let y = load + 0.5 * (2.0 * rel + 0.3).cos() + 0.2 * (4.0 * rel - 1.1).cos() + (out + 0.7).cos() + noise;
        let refs = ReferenceValues::new(rel.rem_euclid(TAU), out.rem_euclid(TAU), motor.rem_euclid(TAU));
        let o = step_traced(&model, &mut state, &RippleInput::new(y, refs), &mut trace)?;
        let [i0, i1, i2] = trace.increment_rad;
        let [q0, q1, q2] = trace.q_nm2;
        writeln!(
            file,
            "{k},{y:.17e},{:.17e},{:.17e},{i0:.17e},{i1:.17e},{i2:.17e},{q0:.17e},{q1:.17e},{q2:.17e},{:.17e}",
            y - o.innovation_nm,
            o.innovation_variance_nm2,
            trace.q_bias_nm2
        )?;
    }
    file.flush()?;
    Ok(())
}
