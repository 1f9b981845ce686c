//! ns per sample of the bench fusions, in one run: the online model-corrected fusion
//! (five sections) against the plain complementary filter (one section), f32 and f64.
//!
//! Both see the same recording (a torsion torque and an accelerometer torque, 4096
//! samples of a chirp plus a pseudo-random sequence), inputs and the whole output through
//! `black_box`, each timed as one plain loop over the recording.
//!
//! Run: `cargo bench -p strainwave-core --bench fusion -- --warm-up-time 1 --measurement-time 2`.

use criterion::{black_box, Criterion, Throughput};
use strainwave_core::fusion::{
    AccelerometerModel, ComplementaryFusion, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel,
};
use strainwave_core::Real;

const N_SAMPLES: usize = 4096;
const FS: f64 = 20_000.0;

fn inputs<T: Real>() -> (Vec<T>, Vec<T>) {
    let mut s = 0x2545_f491_4f6c_dd1d_u64;
    (0..N_SAMPLES)
        .map(|k| {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            let r = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let t = k as f64 / FS;
            let chirp = (std::f64::consts::TAU * (10.0 + 2000.0 * t) * t).sin();
            (T::from_f64(0.1 * chirp + 0.01 * r), T::from_f64(0.08 * chirp - 0.01 * r))
        })
        .unzip()
}

fn bench_scalar<T: Real>(c: &mut Criterion, name: &str) {
    let (torsion, accel) = inputs::<T>();
    let plain = ComplementaryFusion::<T>::kit(T::from_f64(FS)).unwrap();
    let online = OnlineCorrectedFusion::new(
        &TorsionShaftModel::<T>::kit(),
        &AccelerometerModel::<T>::kit(),
        &OnlineCorrectionConfig::kit(),
        T::from_f64(FS),
    )
    .unwrap();
    let mut out = vec![T::ZERO; N_SAMPLES];
    let mut g = c.benchmark_group(format!("fusion/{name}"));
    g.throughput(Throughput::Elements(N_SAMPLES as u64));
    g.bench_function("complementary", |b| {
        b.iter(|| {
            let mut st = Default::default();
            for ((t, a), y) in black_box(&torsion).iter().zip(black_box(&accel)).zip(out.iter_mut()) {
                *y = plain.step(&mut st, *t, *a);
            }
            black_box(&out);
        })
    });
    g.bench_function("online_corrected", |b| {
        b.iter(|| {
            let mut st = Default::default();
            for ((t, a), y) in black_box(&torsion).iter().zip(black_box(&accel)).zip(out.iter_mut()) {
                *y = online.step(&mut st, *t, *a);
            }
            black_box(&out);
        })
    });
    g.finish();
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench_scalar::<f32>(&mut c, "f32");
    bench_scalar::<f64>(&mut c, "f64");
    c.final_summary();
}
