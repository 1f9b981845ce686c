//! Campbell diagram and order slices on a synthetic speed ramp 0 → 3200 rpm (Stoß et al. (2022)
//! Fig. 8): each simulated order's ridge sits on its line, order slices give its
//! amplitude and phase.

use std::f64::consts::TAU;

use strainwave_analysis::campbell::{campbell, integrate_angle_rev, order_slice, CampbellConfig, OrderSliceConfig};
use strainwave_analysis::AnalysisError;

const FS: f64 = 20_000.0;
const RAMP_S: f64 = 8.0;
/// `(mechanical order, amplitude, phase)`: 6th and 12th electrical of a 3-pole-pair
/// machine, and the 1st (unbalance).
const ORDERS: [(f64, f64, f64); 3] = [(18.0, 2.5e-3, 0.3), (36.0, 1.1e-3, -0.8), (1.0, 4.0e-3, 1.2)];

fn ramp() -> (Vec<f64>, Vec<f64>) {
    let n = (RAMP_S * FS) as usize;
    let speed: Vec<f64> = (0..n).map(|k| 3200.0 * k as f64 / n as f64).collect();
    let theta = integrate_angle_rev(&speed, FS, 0.0);
    let mut s = 12345u64;
    let x = theta
        .iter()
        .map(|t| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let noise = 1e-4 * ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            0.1 + noise + ORDERS.iter().map(|(k, a, p)| a * (TAU * k * t + p).cos()).sum::<f64>()
        })
        .collect();
    (x, speed)
}

#[test]
fn ridges_sit_on_their_order_lines() {
    let (x, speed) = ramp();
    let c = campbell(&x, &speed, FS, &CampbellConfig::new(4096, 50.0)).unwrap();
    assert_eq!(c.speed_axis_rpm.len(), c.grid.len());
    for (order, amp, _) in ORDERS {
        // Where the line is clear of DC and of the other orders (6 bins).
        let clear = |p: &&strainwave_analysis::campbell::RidgePoint| {
            p.expected_hz > 6.0 * c.resolution_hz() && 17.0 * p.speed_rpm / 60.0 > 6.0 * c.resolution_hz()
        };
        let ridge: Vec<_> = c.order_ridge(order, 4).into_iter().filter(|p| clear(&p)).collect();
        assert!(ridge.len() > 50, "order {order}: {} frames", ridge.len());
        for p in &ridge {
            // Within one bin of the line at the frame's mean speed, and standing out of
            // the grid at that speed.
            assert!((p.peak_hz - p.expected_hz).abs() <= c.resolution_hz(), "order {order}: {p:?}");
            assert!(p.amplitude > 0.3 * amp && p.amplitude < 1.01 * amp, "order {order}: {p:?}");
        }
    }
    // The grid row of a speed bin has the order lines as its largest values.
    let row = c.speed_axis_rpm.iter().position(|v| (*v - 3025.0).abs() < 1.0).unwrap();
    let k18 = (18.0 * 3025.0 / 60.0 / c.resolution_hz()).round() as usize;
    let grid_row = &c.grid[row];
    let peak = (k18 - 3..=k18 + 3).map(|k| grid_row[k]).fold(0.0, f64::max);
    let far = grid_row[k18 + 40];
    assert!(peak > 100.0 * far, "{peak} {far}");
}

#[test]
fn order_slices_give_amplitude_and_phase() {
    let (x, speed) = ramp();
    for (order, amp, phase) in ORDERS {
        let s = order_slice(&x, &speed, FS, order, &OrderSliceConfig::default()).unwrap();
        assert!(s.amplitude.len() > 40, "{}", s.amplitude.len());
        for i in 0..s.amplitude.len() {
            assert!(
                (s.amplitude[i] / amp - 1.0).abs() < 0.01,
                "order {order} at {} rpm: {}",
                s.speed_rpm[i],
                s.amplitude[i]
            );
            assert!(
                (s.phase_rad[i] - phase).abs() < 0.01,
                "order {order} at {} rpm: {}",
                s.speed_rpm[i],
                s.phase_rad[i]
            );
        }
        assert!(s.speed_rpm.windows(2).all(|w| w[1] > w[0]));
    }
}

#[test]
fn bad_input_is_an_error() {
    let (x, speed) = ramp();
    let cfg = CampbellConfig::new(4096, 50.0);
    assert!(matches!(campbell(&x[..100], &speed[..100], FS, &cfg), Err(AnalysisError::TooShort { .. })));
    let stand = vec![0.0; x.len()];
    assert!(matches!(campbell(&x, &stand, FS, &cfg), Err(AnalysisError::Invalid { what: "speed_rpm", .. })));
    assert!(matches!(
        order_slice(&x, &stand, FS, 18.0, &OrderSliceConfig::default()),
        Err(AnalysisError::Invalid { what: "speed_rpm", .. })
    ));
    let mut bad = speed.clone();
    bad[10] = f64::NAN;
    assert!(matches!(campbell(&x, &bad, FS, &cfg), Err(AnalysisError::NonFinite { what: "speed_rpm", index: 10 })));
    assert!(order_slice(&x, &speed, FS, 0.0, &OrderSliceConfig::default()).is_err());
    assert!(campbell(&x, &speed, -1.0, &cfg).is_err());
    assert!(campbell(&x, &speed, FS, &CampbellConfig::new(4096, 0.0)).is_err());
}
