//! ns per sample of the canceller under the do-no-harm guard against the bare canceller,
//! in the same run: the `full` model (5 orders, bias state), angle input, f64 and f32,
//! over one recording of 4096 samples (a 2× and 4× ripple, a misalignment, a load step).
//!
//! The guard runs the traced step (the same step, recording its intermediate quantities)
//! and its per-line tests on top.
//!
//! Run: `cargo bench -p strainwave-core --bench guard -- --warm-up-time 1 --measurement-time 2`.

use criterion::{black_box, Criterion, Throughput};
use strainwave_core::guard::{Guard, GuardSettings};
use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState};
use strainwave_core::Real;

const N_SAMPLES: usize = 4096;

fn inputs<T: Real>() -> Vec<RippleInput<T>> {
    (0..N_SAMPLES)
        .map(|k| {
            let phi = 0.16 * k as f64;
            let out = phi / 100.0;
            let load = if k > N_SAMPLES / 2 { 5.0 } else { 1.0 };
            let y = load + 0.3 * (2.0 * phi).sin() + 0.1 * (4.0 * phi + 1.0).sin() + 0.8 * (out + 0.7).sin();
            let c = T::from_f64;
            RippleInput::new(c(y), ReferenceValues::new(c(phi.rem_euclid(std::f64::consts::TAU)), c(out), c(phi)))
        })
        .collect()
}

fn bench<T: Real>(c: &mut Criterion, name: &str) {
    let model = RippleModel::<T, 5>::full(T::from_f64(1000.0), T::from_f64(0.0162)).unwrap();
    let xs = inputs::<T>();
    let mut g = c.benchmark_group(format!("guard-{name}"));
    g.throughput(Throughput::Elements(N_SAMPLES as u64));
    g.bench_function("bare step", |b| {
        b.iter(|| {
            let mut state = RippleState::new(&model);
            for x in &xs {
                black_box(step(&model, &mut state, black_box(x)).ok());
            }
        })
    });
    g.bench_function("guarded step", |b| {
        b.iter(|| {
            let mut guard = Guard::new(&model, GuardSettings::default());
            for x in &xs {
                black_box(guard.step(&model, black_box(x)).ok());
            }
        })
    });
    g.finish();
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench::<f64>(&mut c, "f64");
    bench::<f32>(&mut c, "f32");
    c.final_summary();
}
