//! The bench simulation loop: scenario in, one row per sample out, measured signals and
//! the truth.

use std::f64::consts::TAU;

use super::model::{engage, BenchFluxMap, BenchModel, BenchState, Currents};
use super::{BenchProfile, BenchScenario, SweepSpacing};
use crate::error::SimError;
use crate::rng::Rng;

/// Measured columns, in order:
///
/// | column | unit | what |
/// |---|---|---|
/// | `time` | s | sample instant |
/// | `speed_rpm` | rpm | rotor speed (drive's speed channel, with noise) |
/// | `rotor_angle` | rad | DUT encoder, rotor in housing (whole counts) |
/// | `torsion_torque` | N·m | torsion sensor (noise, clipped at its range) |
/// | `accel_1`, `accel_2` | m/s² | the two accelerometers (noise, vibration, clipped) |
/// | `accel_torque` | N·m | `J_S (a1 + a2) / (2R)` as the bench computes it |
/// | `current_d`, `current_q` | A | measured rotor-frame currents |
/// | `inner_torque` | N·m | eq. 12 online: flux map, measured currents, encoder angle |
/// | `model_torque` | N·m | eq. 13 with the angle-averaged flux (the paper's sweep reference) |
pub const MEASURED_COLUMNS: &[&str] = &[
    "time",
    "speed_rpm",
    "rotor_angle",
    "torsion_torque",
    "accel_1",
    "accel_2",
    "accel_torque",
    "current_d",
    "current_q",
    "inner_torque",
    "model_torque",
];

/// Truth columns, in order: `true_dut_torque` (air gap: eq. 12 + cogging, N·m),
/// `true_inner_torque` (eq. 12), `true_cogging_torque`, `true_shaft_torque` (`k δ + c δ̇`),
/// `true_accel_torque` (`−J_S ω̇_S`, ideal accelerometers), `true_brake_torque`,
/// `true_rotor_speed_rpm`, `true_rotor_angle` (`θ_R`), `true_stator_angle` (`θ_S`),
/// `true_electrical_angle` (`p (θ_R − θ_S)`), `true_current_d`, `true_current_q`.
pub const TRUE_COLUMNS: &[&str] = &[
    "true_dut_torque",
    "true_inner_torque",
    "true_cogging_torque",
    "true_shaft_torque",
    "true_accel_torque",
    "true_brake_torque",
    "true_rotor_speed_rpm",
    "true_rotor_angle",
    "true_stator_angle",
    "true_electrical_angle",
    "true_current_d",
    "true_current_q",
];

/// Largest `|ω h|` of the fastest rate per RK4 sub-step (as [`crate::simulator::MAX_OMEGA_H`]).
pub const MAX_OMEGA_H: f64 = 0.6;

const RPM_PER_RAD_S: f64 = 60.0 / TAU;

/// A running bench simulation.
pub struct BenchSimulator {
    scenario: BenchScenario,
    model: BenchModel,
    map: Box<BenchFluxMap>,
    rng: Rng,
    state: BenchState,
    k: u64,
    n_samples: u64,
    dt_s: f64,
    n_sub: u32,
    encoder_step_rad: f64,
    kp: f64,
    ki: f64,
    integral_nm: f64,
    clipped_torsion: u64,
    clipped_accel: u64,
}

impl BenchSimulator {
    /// Prepares a run; the RK4 sub-step count follows from the fastest rate
    /// (`|ω h| ≤ MAX_OMEGA_H`).
    ///
    /// ```
    /// let s = strainwave_sim::bench::preset("kit-bench-sweep").unwrap();
    /// let sim = strainwave_sim::bench::BenchSimulator::new(&s).unwrap();
    /// assert_eq!(sim.len(), 800_000);
    /// assert!(sim.substeps() >= 5); // 8 kHz forcing at 20 kHz
    /// ```
    pub fn new(scenario: &BenchScenario) -> Result<Self, SimError> {
        let model = BenchModel::new(scenario)?;
        let n_sub = ((model.max_rate_rad_s(scenario) / scenario.sample_rate_hz / MAX_OMEGA_H).ceil() as u32).max(1);
        Self::with_substeps(scenario, n_sub)
    }

    /// Prepares a run with `n_sub` (≥ 1) RK4 sub-steps per sample.
    pub fn with_substeps(scenario: &BenchScenario, n_sub: u32) -> Result<Self, SimError> {
        let model = BenchModel::new(scenario)?;
        let map = model.flux_map()?;
        let (kp, ki) = match &scenario.profile {
            BenchProfile::SpeedRamp { speed_loop_bandwidth_hz, .. } => {
                let wc = TAU * speed_loop_bandwidth_hz;
                let j = model.drive_inertia_kg_m2();
                (j * wc, j * wc * wc / 4.0)
            }
            BenchProfile::CurrentSweep { .. } => (0.0, 0.0),
        };
        Ok(Self {
            rng: Rng::new(scenario.seed),
            state: BenchState::default(),
            k: 0,
            n_samples: (scenario.duration_s * scenario.sample_rate_hz).round() as u64,
            dt_s: 1.0 / scenario.sample_rate_hz,
            n_sub: n_sub.clamp(1, 10_000),
            encoder_step_rad: TAU / scenario.encoder.counts_per_rev as f64,
            kp,
            ki,
            integral_nm: 0.0,
            clipped_torsion: 0,
            clipped_accel: 0,
            scenario: scenario.clone(),
            model,
            map,
        })
    }

    /// Column names of the rows, in order.
    pub fn columns(&self) -> Vec<&'static str> {
        MEASURED_COLUMNS.iter().chain(TRUE_COLUMNS).copied().collect()
    }

    /// Rows the run will produce.
    pub fn len(&self) -> u64 {
        self.n_samples
    }

    /// Whether the run produces no rows.
    pub fn is_empty(&self) -> bool {
        self.n_samples == 0
    }

    /// RK4 sub-steps per sample.
    pub fn substeps(&self) -> u32 {
        self.n_sub
    }

    /// The scenario.
    pub fn scenario(&self) -> &BenchScenario {
        &self.scenario
    }

    /// The dynamics.
    pub fn model(&self) -> &BenchModel {
        &self.model
    }

    /// Samples clipped so far: `(torsion sensor, accelerometers)`.
    pub fn clipped_samples(&self) -> (u64, u64) {
        (self.clipped_torsion, self.clipped_accel)
    }

    /// Sweep phase `φ(t)`, rad.
    fn sweep_phase(&self, t_s: f64) -> f64 {
        let BenchProfile::CurrentSweep { from_hz, to_hz, spacing, .. } = self.scenario.profile else {
            return 0.0;
        };
        let dur = self.scenario.duration_s;
        let ratio = to_hz / from_hz;
        match spacing {
            SweepSpacing::Log if ratio > 1.0 => {
                let l = ratio.ln();
                TAU * from_hz * dur / l * ((l * t_s / dur).exp() - 1.0)
            }
            _ => TAU * (from_hz * t_s + 0.5 * (to_hz - from_hz) * t_s * t_s / dur),
        }
    }

    /// Currents of the sweep at `t_s` (continuous: an ideal current loop).
    fn sweep_currents(&self, t_s: f64) -> Currents {
        match self.scenario.profile {
            BenchProfile::CurrentSweep { amplitude_a, .. } => {
                Currents { d_a: 0.0, q_a: amplitude_a * self.sweep_phase(t_s).cos() }
            }
            BenchProfile::SpeedRamp { .. } => Currents::default(),
        }
    }

    /// Writes the next row into `row` (length = `columns().len()`); `false` when done.
    pub fn next_row(&mut self, row: &mut Vec<f64>) -> bool {
        if self.k >= self.n_samples {
            return false;
        }
        let t = self.k as f64 * self.dt_s;
        let x = self.state;
        let speed_meas_rpm =
            x.rotor_speed_rad_s * RPM_PER_RAD_S + self.scenario.encoder.speed_noise_rpm * self.rng.normal();

        // The drive: a PI speed loop held over the sample, or the sweep.
        let held = match self.scenario.profile {
            BenchProfile::SpeedRamp { from_rpm, to_rpm, ramp_s, d_current_a, .. } => {
                let frac = (t / ramp_s).min(1.0);
                let ref_rad_s = (from_rpm + (to_rpm - from_rpm) * frac) / RPM_PER_RAD_S;
                let accel = if t < ramp_s { (to_rpm - from_rpm) / ramp_s / RPM_PER_RAD_S } else { 0.0 };
                let e = ref_rad_s - speed_meas_rpm / RPM_PER_RAD_S;
                let torque = self.kp * e + self.integral_nm + self.model.drive_inertia_kg_m2() * accel;
                self.integral_nm += self.ki * e * self.dt_s;
                let q = (torque / self.model.torque_constant_nm_per_a()).clamp(-20.0, 20.0);
                Some(Currents { d_a: d_current_a * engage(t, self.scenario.brake.engage_s), q_a: q })
            }
            BenchProfile::CurrentSweep { .. } => None,
        };
        let cur = held.unwrap_or_else(|| self.sweep_currents(t));

        // Truth.
        let m = &self.model;
        let th_e = x.rotor_in_housing_rad();
        let inner = m.inner_torque_nm(th_e, cur);
        let cog = m.cogging_torque_nm(th_e);
        let shaft = m.shaft_torque_nm(&x);
        let dx = m.derivative(&x, t, cur);
        let accel_truth_nm = -m.stator_inertia_kg_m2() * dx.stator_speed_rad_s;
        let brake = m.brake_torque_nm(t, x.brake_speed_rad_s);

        // Measurements.
        let s = &self.scenario;
        let ts_range = s.torsion_sensor.range_nm;
        let ts_raw = shaft + s.torsion_sensor.noise_nm * self.rng.normal();
        let ts = ts_raw.clamp(-ts_range, ts_range);
        self.clipped_torsion += u64::from(ts != ts_raw);
        let a = &s.accelerometers;
        let tangential = -a.radius_m * dx.stator_speed_rad_s;
        let vib: f64 = a
            .vibration
            .iter()
            .map(|v| {
                let phase = match (v.frequency_hz, v.order_mech) {
                    (Some(f), _) => TAU * f * t,
                    (None, Some(o)) => o * x.rotor_angle_rad,
                    (None, None) => 0.0,
                };
                v.amplitude_m_s2 * phase.sin()
            })
            .sum();
        let a1_raw = tangential + vib + a.noise_m_s2_rms * self.rng.normal();
        let a2_raw = (tangential - vib) * (1.0 + a.gain_error_2) + a.noise_m_s2_rms * self.rng.normal();
        let (a1, a2) = (a1_raw.clamp(-a.range_m_s2, a.range_m_s2), a2_raw.clamp(-a.range_m_s2, a.range_m_s2));
        self.clipped_accel += u64::from(a1 != a1_raw || a2 != a2_raw);
        let accel_torque = m.stator_inertia_kg_m2() * (a1 + a2) / (2.0 * a.radius_m);
        let enc = (th_e / self.encoder_step_rad).floor() * self.encoder_step_rad;
        let noise_i = s.encoder.current_noise_a;
        let (id_m, iq_m) = (cur.d_a + noise_i * self.rng.normal(), cur.q_a + noise_i * self.rng.normal());
        let p = m.pole_pairs();
        let inner_online = self.map.torque_nm(p, p * enc, id_m, iq_m);
        let model_torque = self.map.fundamental_torque_nm(p, id_m, iq_m);

        row.clear();
        row.extend_from_slice(&[
            t,
            speed_meas_rpm,
            enc,
            ts,
            a1,
            a2,
            accel_torque,
            id_m,
            iq_m,
            inner_online,
            model_torque,
            inner + cog,
            inner,
            cog,
            shaft,
            accel_truth_nm,
            brake,
            x.rotor_speed_rad_s * RPM_PER_RAD_S,
            x.rotor_angle_rad,
            x.stator_angle_rad,
            p * th_e,
            cur.d_a,
            cur.q_a,
        ]);

        // Advance over the sample.
        let h = self.dt_s / self.n_sub as f64;
        let mut state = self.state;
        let this = &*self;
        let currents = |time: f64| match held {
            Some(c) => c,
            None => this.sweep_currents(time),
        };
        for j in 0..self.n_sub {
            self.model.rk4_step(&mut state, t + j as f64 * h, h, &currents);
        }
        self.state = state;
        self.k += 1;
        true
    }
}

/// A whole run in memory: the kept column names and one `Vec` per column.
#[derive(Debug, Clone)]
pub struct BenchRecording {
    /// Column names.
    pub columns: Vec<&'static str>,
    /// Column data, `data[c][k]`.
    pub data: Vec<Vec<f64>>,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
}

impl BenchRecording {
    /// A column by name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().position(|c| *c == name).map(|i| self.data[i].as_slice())
    }
}

/// Runs a scenario to the end in memory, keeping the columns named in `keep` (all when
/// `None`; an unknown name is an error naming it).
///
/// ```
/// let mut s = strainwave_sim::bench::preset("kit-bench").unwrap();
/// s.duration_s = 0.01;
/// let rec = strainwave_sim::bench::simulate_bench(&s, Some(&["time", "torsion_torque"])).unwrap();
/// assert_eq!(rec.column("time").unwrap().len(), 200);
/// assert!(rec.column("accel_1").is_none());
/// ```
pub fn simulate_bench(scenario: &BenchScenario, keep: Option<&[&str]>) -> Result<BenchRecording, SimError> {
    let mut sim = BenchSimulator::new(scenario)?;
    let all = sim.columns();
    let idx: Vec<usize> = match keep {
        None => (0..all.len()).collect(),
        Some(names) => names
            .iter()
            .map(|n| {
                all.iter()
                    .position(|c| c == n)
                    .ok_or_else(|| SimError::invalid("columns", format!("no column `{n}` (known: {})", all.join(", "))))
            })
            .collect::<Result<_, _>>()?,
    };
    let mut data = vec![Vec::with_capacity(sim.len() as usize); idx.len()];
    let mut row = Vec::with_capacity(all.len());
    while sim.next_row(&mut row) {
        for (d, &i) in data.iter_mut().zip(&idx) {
            d.push(row[i]);
        }
    }
    Ok(BenchRecording { columns: idx.iter().map(|&i| all[i]).collect(), data, sample_rate_hz: scenario.sample_rate_hz })
}
