//! Simulated samples per second for the `taghirad` preset, beside the same twin with
//! a fixed, conservative 10 RK4 sub-steps per sample (what a hand-set integrator
//! without the stiffness-derived step would use).
//!
//! `cargo bench -p strainwave-sim --bench simulate`

use criterion::{black_box, Criterion, Throughput};
use strainwave_sim::{presets::preset, Simulator};

const SECONDS: f64 = 10.0;

fn run(sim: &mut Simulator) -> f64 {
    let mut row = Vec::with_capacity(24);
    let mut acc = 0.0;
    while sim.next_row(&mut row) {
        acc += row[6];
    }
    acc
}

fn bench(c: &mut Criterion) {
    let mut s = preset("taghirad").unwrap();
    s.duration_s = SECONDS;
    let samples = (SECONDS * s.sample_rate_hz) as u64;
    let mut g = c.benchmark_group("simulate_taghirad_10s");
    g.throughput(Throughput::Elements(samples));
    g.sample_size(10);
    g.bench_function("auto_substeps", |b| b.iter(|| run(&mut Simulator::new(black_box(&s)).unwrap())));
    g.bench_function("fixed_10_substeps", |b| {
        b.iter(|| run(&mut Simulator::with_substeps(black_box(&s), 10).unwrap()))
    });
    g.finish();
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench(&mut c);
    c.final_summary();
}
