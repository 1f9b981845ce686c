//! ns per sample of the ripple canceller against the same model in a dense nalgebra
//! Kalman filter and in adskalman, and the multi-joint bank (ns per sample per joint).
//!
//! Same model in each (`Q = 1e-3 I`, `R = 1`, `P0 = I`, `C` = first component of each
//! oscillator), same torques, inputs and whole outputs through `black_box`, each timed
//! as one plain loop over the recording (the same loop for every variant). What each
//! includes:
//! - strainwave: angle input (wrapped angles → increments, sine/cosine per reference),
//!   every robustness check (finite inputs, gaps, jumps, order status, covariance health),
//!   innovation variance, NIS and flags.
//! - nalgebra-dense: the textbook filter, given the increments; builds `Φ` (one sine/cosine
//!   per order), no checks.
//! - adskalman: update (forced symmetric) then predict, given the increments; builds `Φ`.
//!
//! - alternating: two joints, each its own state, stepped one after the other by `step`
//!   (ns per joint): the one-joint step's dependency chain, seen from outside.
//! - banks (`step_many`): as strainwave above, for `J` joints at once.
//!
//! On x86-64 CPUs with AVX2 and FMA the library runs its build for them (chosen at run
//! time; its multiply–adds fused, so results equal to rounding), one joint and banks
//! alike; other CPUs run the portable build. nalgebra and adskalman run
//! as compiled (no run-time choice of build: they form no fused multiply–add).
//!
//! Run: `cargo bench -p strainwave-core --bench ripple -- --warm-up-time 1 --measurement-time 2`,
//! then `scripts/bench-summary ripple` for the fastest, 10th-percentile and median
//! samples beside criterion's slope (on a shared machine the slope takes in whatever
//! else ran).
//! (optionally with `RUSTFLAGS="-C target-cpu=native"`: every variant then gets the same
//! flags; the committed configuration targets any x86-64).

use adskalman::{CovarianceUpdateMethod, ObservationModel, StateAndCovariance, TransitionModelLinearNoControl};
use criterion::{black_box, Bencher, Criterion, Throughput};
use nalgebra::{Const, OMatrix, OVector, RealField, SMatrix, SVector, U1};
use std::time::Instant;
use strainwave_core::ripple::{
    step, step_many, BankInput, BankOutput, ReferenceValues, RippleBank, RippleInput, RippleModel, RippleState,
};
use strainwave_core::Real;

const N_SAMPLES: usize = 4096;

/// One recorded sample: torque, wrapped reference angles and the orders' increments.
#[derive(Clone, Copy)]
struct Sample {
    y: f64,
    rel: f64,
    out: f64,
    inc: [f64; 3],
}

/// A 150 rad/s joint (N = 100): ripple at 2×/4× φ, misalignment at 1× output, noise.
fn samples(phase: f64) -> Vec<Sample> {
    let mut seed = 0x2545_F491_4F6C_DD1D_u64;
    (0..N_SAMPLES)
        .map(|k| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let noise = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let motor = phase + 0.15 * k as f64;
            let (out, rel) = (-motor / 100.0, motor * 1.01);
            let d = 0.15 * 1.01;
            Sample {
                y: 5.0 + 0.5 * (2.0 * rel).cos() + 0.2 * (4.0 * rel).cos() + (out + 0.7).cos() + 0.1 * noise,
                rel: rel.rem_euclid(std::f64::consts::TAU),
                out: out.rem_euclid(std::f64::consts::TAU),
                inc: [2.0 * d, 4.0 * d, -0.0015],
            }
        })
        .collect()
}

/// Times `iters` samples of the recording in one plain loop, each call going on where
/// the last one stopped (wrapping around): the same loop for every variant, so what
/// differs is the step itself. Every output goes through `black_box`, so nothing the
/// step computes can be left out.
fn over_the_recording(b: &mut Bencher, mut sample: impl FnMut(usize)) {
    let mut next = 0usize;
    b.iter_custom(|iters| {
        let first = next;
        let start = Instant::now();
        for i in 0..iters as usize {
            sample((first + i) % N_SAMPLES);
        }
        let elapsed = start.elapsed();
        next = (first + iters as usize) % N_SAMPLES;
        elapsed
    });
}

fn inputs<T: Real>(data: &[Sample]) -> Vec<RippleInput<T>> {
    let c = T::from_f64;
    data.iter().map(|s| RippleInput::new(c(s.y), ReferenceValues::new(c(s.rel), c(s.out), T::ZERO))).collect()
}

fn bench_strainwave<T: Real, const M: usize>(c: &mut Criterion, name: &str, model: RippleModel<T, M>) {
    let data = inputs::<T>(&samples(0.0));
    let mut state = RippleState::new(&model);
    c.bench_function(name, |b| {
        over_the_recording(b, |k| {
            // The whole result (every output, or the error) is kept.
            let _ = black_box(step(&model, &mut state, black_box(&data[k])));
        })
    });
}

/// Two joints, each its own `RippleState` and recording, stepped one after the other
/// by `step` (per joint). Beside the one-joint row this shows how much of a step's time
/// is its dependency chain (the covariance recursion from one sample to the next):
/// independent joints' chains overlap in the CPU, one joint's cannot.
fn bench_alternating<T: Real, const M: usize>(c: &mut Criterion, name: &str, model: RippleModel<T, M>) {
    let data = [inputs::<T>(&samples(0.0)), inputs::<T>(&samples(0.37))];
    let mut states = [RippleState::new(&model), RippleState::new(&model)];
    let mut group = c.benchmark_group("ripple/alternating");
    group.throughput(Throughput::Elements(2));
    group.bench_function(name, |b| {
        over_the_recording(b, |k| {
            for (state, data) in states.iter_mut().zip(&data) {
                let _ = black_box(step(&model, state, black_box(&data[k])));
            }
        })
    });
    group.finish();
}

/// The textbook prediction-type filter (Taghirad and Bélanger, 1999) with dense nalgebra algebra.
struct Dense<T: RealField + Copy, const N: usize> {
    x: SVector<T, N>,
    p: SMatrix<T, N, N>,
    c: SMatrix<T, 1, N>,
    q: SMatrix<T, N, N>,
    r: T,
}

impl<T: RealField + Copy, const N: usize> Dense<T, N> {
    fn new() -> Self {
        let mut c = SMatrix::<T, 1, N>::zeros();
        for i in (0..N).step_by(2) {
            c[(0, i)] = T::one();
        }
        let q = SMatrix::<T, N, N>::identity() * nalgebra::convert::<f64, T>(1e-3);
        Self { x: SVector::zeros(), p: SMatrix::identity(), c, q, r: T::one() }
    }

    fn step(&mut self, y: T, inc: &[T]) -> T {
        let mut phi = SMatrix::<T, N, N>::zeros();
        for (i, &a) in inc.iter().enumerate().take(N / 2) {
            let (s, co) = a.sin_cos();
            phi[(2 * i, 2 * i)] = co;
            phi[(2 * i, 2 * i + 1)] = s;
            phi[(2 * i + 1, 2 * i)] = -s;
            phi[(2 * i + 1, 2 * i + 1)] = co;
        }
        let y_hat = (self.c * self.x)[(0, 0)];
        let pct = self.p * self.c.transpose();
        let s = self.r + (self.c * pct)[(0, 0)];
        let k = phi * pct / s;
        self.x = phi * self.x + k * (y - y_hat);
        self.p = self.q + (phi - k * self.c) * self.p * phi.transpose();
        y - y_hat
    }
}

fn bench_dense<T: RealField + Copy, const N: usize>(c: &mut Criterion, name: &str) {
    let data = samples(0.0);
    let conv = |v: f64| nalgebra::convert::<f64, T>(v);
    let ys: Vec<T> = data.iter().map(|s| conv(s.y)).collect();
    let incs: Vec<[T; 3]> = data.iter().map(|s| s.inc.map(conv)).collect();
    let mut kf = Dense::<T, N>::new();
    c.bench_function(name, |b| {
        over_the_recording(b, |k| {
            black_box(kf.step(black_box(ys[k]), black_box(&incs[k])));
        })
    });
}

/// The same model through adskalman's traits: update (Kalman form) then predict.
struct AdsTransition<T: RealField, const N: usize> {
    f: OMatrix<T, Const<N>, Const<N>>,
    ft: OMatrix<T, Const<N>, Const<N>>,
    q: OMatrix<T, Const<N>, Const<N>>,
}

struct AdsObservation<T: RealField, const N: usize> {
    h: OMatrix<T, U1, Const<N>>,
    ht: OMatrix<T, Const<N>, U1>,
    r: OMatrix<T, U1, U1>,
}

macro_rules! ads_impl {
    ($n:literal) => {
        impl<T: RealField + Copy> TransitionModelLinearNoControl<T, Const<$n>> for AdsTransition<T, $n> {
            fn F(&self) -> &OMatrix<T, Const<$n>, Const<$n>> {
                &self.f
            }
            fn FT(&self) -> &OMatrix<T, Const<$n>, Const<$n>> {
                &self.ft
            }
            fn Q(&self) -> &OMatrix<T, Const<$n>, Const<$n>> {
                &self.q
            }
        }
        impl<T: RealField + Copy> ObservationModel<T, Const<$n>, U1> for AdsObservation<T, $n> {
            fn H(&self) -> &OMatrix<T, U1, Const<$n>> {
                &self.h
            }
            fn HT(&self) -> &OMatrix<T, Const<$n>, U1> {
                &self.ht
            }
            fn R(&self) -> &OMatrix<T, U1, U1> {
                &self.r
            }
        }
    };
}
ads_impl!(4);
ads_impl!(6);

macro_rules! bench_ads {
    ($fn_name:ident, $n:literal) => {
        fn $fn_name<T: RealField + Copy>(c: &mut Criterion, name: &str) {
            let data = samples(0.0);
            let conv = |v: f64| nalgebra::convert::<f64, T>(v);
            let ys: Vec<T> = data.iter().map(|s| conv(s.y)).collect();
            let incs: Vec<[T; 3]> = data.iter().map(|s| s.inc.map(conv)).collect();
            let mut h = OMatrix::<T, U1, Const<$n>>::zeros();
            for i in (0..$n).step_by(2) {
                h[(0, i)] = T::one();
            }
            let obs = AdsObservation::<T, $n> { h, ht: h.transpose(), r: OMatrix::<T, U1, U1>::identity() };
            let mut trans = AdsTransition::<T, $n> {
                f: SMatrix::<T, $n, $n>::identity(),
                ft: SMatrix::<T, $n, $n>::identity(),
                q: OMatrix::<T, Const<$n>, Const<$n>>::identity() * conv(1e-3),
            };
            let mut prior = StateAndCovariance::new(OVector::<T, Const<$n>>::zeros(), SMatrix::<T, $n, $n>::identity());
            c.bench_function(name, |b| {
                over_the_recording(b, |k| {
                    let mut phi = OMatrix::<T, Const<$n>, Const<$n>>::zeros();
                    for (i, &a) in black_box(&incs[k]).iter().enumerate().take($n / 2) {
                        let (s, co) = a.sin_cos();
                        phi[(2 * i, 2 * i)] = co;
                        phi[(2 * i, 2 * i + 1)] = s;
                        phi[(2 * i + 1, 2 * i)] = -s;
                        phi[(2 * i + 1, 2 * i + 1)] = co;
                    }
                    let y = OVector::<T, U1>::new(black_box(ys[k]));
                    let post = obs
                        .update(&prior, &y, CovarianceUpdateMethod::OptimalKalmanForcedSymmetric)
                        .unwrap_or_else(|_| prior.clone());
                    trans.f = phi;
                    trans.ft = phi.transpose();
                    prior = trans.predict(&post);
                    black_box(&prior);
                })
            });
        }
    };
}
bench_ads!(bench_ads4, 4);
bench_ads!(bench_ads6, 6);

fn bench_bank<T: Real, const M: usize, const JOINTS: usize>(c: &mut Criterion, name: &str, model: RippleModel<T, M>) {
    let joints: Vec<Vec<Sample>> = (0..JOINTS).map(|j| samples(0.37 * j as f64)).collect();
    let cv = T::from_f64;
    let inputs: Vec<BankInput<T, JOINTS>> = (0..N_SAMPLES)
        .map(|k| {
            let lane = |f: &dyn Fn(&Sample) -> f64| -> [T; JOINTS] { core::array::from_fn(|j| cv(f(&joints[j][k]))) };
            BankInput::new(lane(&|s| s.y), ReferenceValues::new(lane(&|s| s.rel), lane(&|s| s.out), [T::ZERO; JOINTS]))
        })
        .collect();
    let mut bank = RippleBank::<T, M, JOINTS>::new(&model);
    let mut out = BankOutput::default();
    let mut group = c.benchmark_group("ripple/bank");
    group.throughput(Throughput::Elements(JOINTS as u64));
    group.bench_function(name, |b| {
        over_the_recording(b, |k| {
            step_many(&model, &mut bank, black_box(&inputs[k]), &mut out);
            black_box(&out);
        })
    });
    group.finish();
}

fn all(c: &mut Criterion) {
    bench_strainwave(c, "ripple/4-state/f64/strainwave", RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap());
    bench_dense::<f64, 4>(c, "ripple/4-state/f64/nalgebra-dense");
    bench_ads4::<f64>(c, "ripple/4-state/f64/adskalman");
    bench_strainwave(c, "ripple/4-state/f32/strainwave", RippleModel::<f32, 2>::taghirad_4th_order(1000.0).unwrap());
    bench_dense::<f32, 4>(c, "ripple/4-state/f32/nalgebra-dense");
    bench_ads4::<f32>(c, "ripple/4-state/f32/adskalman");
    bench_strainwave(c, "ripple/6-state/f64/strainwave", RippleModel::<f64, 3>::taghirad_6th_order(1000.0).unwrap());
    bench_dense::<f64, 6>(c, "ripple/6-state/f64/nalgebra-dense");
    bench_ads6::<f64>(c, "ripple/6-state/f64/adskalman");
    bench_strainwave(c, "ripple/6-state/f32/strainwave", RippleModel::<f32, 3>::taghirad_6th_order(1000.0).unwrap());
    bench_dense::<f32, 6>(c, "ripple/6-state/f32/nalgebra-dense");
    bench_ads6::<f32>(c, "ripple/6-state/f32/adskalman");
    bench_strainwave(c, "ripple/7-state-product/f64/strainwave", RippleModel::<f64, 3>::product(1000.0, 0.1).unwrap());
    bench_strainwave(c, "ripple/7-state-product/f32/strainwave", RippleModel::<f32, 3>::product(1000.0, 0.1).unwrap());
    bench_strainwave(c, "ripple/11-state-full/f64/strainwave", RippleModel::<f64, 5>::full(1000.0, 0.1).unwrap());
    bench_strainwave(c, "ripple/11-state-full/f32/strainwave", RippleModel::<f32, 5>::full(1000.0, 0.1).unwrap());
    bench_alternating(c, "6-state/f64/2-joints", RippleModel::<f64, 3>::taghirad_6th_order(1000.0).unwrap());
    bench_bank::<f64, 3, 2>(c, "6-state/f64/2-joints", RippleModel::taghirad_6th_order(1000.0).unwrap());
    bench_bank::<f32, 3, 8>(c, "6-state/f32/8-joints", RippleModel::taghirad_6th_order(1000.0).unwrap());
    bench_bank::<f32, 3, 16>(c, "6-state/f32/16-joints", RippleModel::taghirad_6th_order(1000.0).unwrap());
    bench_bank::<f64, 3, 8>(c, "6-state/f64/8-joints", RippleModel::taghirad_6th_order(1000.0).unwrap());
    bench_bank::<f32, 3, 8>(c, "7-state-product/f32/8-joints", RippleModel::product(1000.0, 0.1).unwrap());
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    all(&mut c);
    c.final_summary();
}
