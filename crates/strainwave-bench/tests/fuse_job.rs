//! The fuse job over rows in memory (as the Python package feeds it): the streamed
//! complementary method is the core's filter stepped over the rows, the offline spectral
//! method is the analysis crate's combination, and bad input is a one-line error naming
//! the input and its row.

use std::path::PathBuf;

use anyhow::Result;
use strainwave_analysis::bench::spectral_combination;
use strainwave_bench::{BenchConfig, Fuse, Method};
use strainwave_core::fusion::{ComplementaryFusion, CrossoverOrder};
use strainwave_io::IoError;
use strainwave_joint::run::{RowSink, RowSource};

/// A power of two, so that every time step `k / FS_HZ` is exact and the job's rate (the
/// median step) is this rate to the bit.
const FS_HZ: f64 = 2048.0;
const CROSSOVER_HZ: f64 = 50.0;

struct Rows {
    columns: Vec<String>,
    rows: Vec<Vec<f64>>,
    next: usize,
}

impl RowSource for Rows {
    fn columns(&self) -> &[String] {
        &self.columns
    }
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        row.clear();
        let Some(r) = self.rows.get(self.next) else { return Ok(false) };
        row.extend_from_slice(r);
        self.next += 1;
        Ok(true)
    }
    fn rows_read(&self) -> u64 {
        self.next as u64
    }
}

struct Sink<'a>(&'a mut Vec<Vec<f64>>);

impl RowSink for Sink<'_> {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        self.0.push(row.to_vec());
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
    fn finish(self) -> Result<u64, IoError> {
        Ok(self.0.len() as u64)
    }
}

/// A bench config file with an accelerometer-torque column.
fn config(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strainwave-bench-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bench.toml");
    std::fs::write(
        &path,
        format!(
            "stator_inertia_kg_m2 = 1.0e-3\nradius_m = 0.5\ncrossover_hz = {CROSSOVER_HZ}\norder = 2\n\n\
             [columns]\ntorsion = \"torsion\"\naccel_torque = \"accel\"\n"
        ),
    )
    .unwrap();
    path
}

/// 0.5 s of a torque step seen by a lagging torsion path and a noisy accelerometer path.
fn rows() -> Rows {
    let n = (0.5 * FS_HZ) as usize;
    let rows = (0..n)
        .map(|k| {
            let t = k as f64 / FS_HZ;
            let torque = if t > 0.1 { 2.0 } else { 0.5 };
            // The torsion path follows the step from 0.5 to 2 N·m with a 12.5 ms lag.
            let torsion = 0.5 + 1.5 * (1.0 - (-(t - 0.1).max(0.0) * 80.0).exp());
            let accel = torque + 0.05 * (2.0 * std::f64::consts::PI * 300.0 * t).sin();
            vec![t, torsion, accel]
        })
        .collect();
    Rows { columns: vec!["time".into(), "torsion".into(), "accel".into()], rows, next: 0 }
}

fn run(method: Method, source: &mut Rows, reference: Option<&str>) -> Result<(Vec<Vec<f64>>, String)> {
    let path = config(method.name());
    let cfg = BenchConfig::load(&path);
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
    let fuse = Fuse::new(cfg?, &path, method)?;
    let mut out = Vec::new();
    let mut said = String::new();
    let mut say = |t: &str| -> Result<()> {
        said.push_str(t);
        Ok(())
    };
    let rows = fuse.run(
        source,
        |names| {
            assert_eq!(names, ["time", "torsion", "accel", "fused_torque"]);
            Ok(Sink(&mut out))
        },
        "bench.csv",
        reference,
        &mut say,
    )?;
    assert_eq!(rows as usize, out.len());
    Ok((out, said))
}

#[test]
fn streamed_complementary_is_the_core_filter_over_the_rows() {
    let mut src = rows();
    let input = src.rows.clone();
    let (out, said) = run(Method::Complementary, &mut src, None).unwrap();
    assert!(said.is_empty(), "{said}");
    let f = ComplementaryFusion::new(CROSSOVER_HZ, FS_HZ, CrossoverOrder::Second).unwrap();
    let mut st = f.settled_state(input[0][1], input[0][2]);
    for (k, (i, o)) in input.iter().zip(&out).enumerate() {
        assert_eq!(&o[..3], &i[..], "row {} passes through", k + 1);
        let y = f.step(&mut st, i[1], i[2]);
        assert_eq!(o[3].to_bits(), y.to_bits(), "row {}", k + 1);
    }
    // The step is followed: the fused torque ends near 2 N·m.
    assert!((out.last().unwrap()[3] - 2.0).abs() < 0.1, "{}", out.last().unwrap()[3]);
}

#[test]
fn offline_spectral_is_the_analysis_combination() {
    let mut src = rows();
    let torsion: Vec<f64> = src.rows.iter().map(|r| r[1]).collect();
    let accel: Vec<f64> = src.rows.iter().map(|r| r[2]).collect();
    let (out, said) = run(Method::Spectral, &mut src, Some("torsion")).unwrap();
    let expected = spectral_combination(&torsion, &accel, FS_HZ, CROSSOVER_HZ).unwrap();
    assert_eq!(out.len(), expected.len());
    for (k, (o, y)) in out.iter().zip(&expected).enumerate() {
        assert_eq!(o[3].to_bits(), y.to_bits(), "row {}", k + 1);
    }
    assert!(said.starts_with("spectral against `torsion`"), "{said}");
}

#[test]
fn bad_input_is_a_one_line_error_naming_it() {
    let mut src = rows();
    src.columns[2] = "accel_torque".into();
    let e = run(Method::Complementary, &mut src, None).unwrap_err();
    assert_eq!(
        strainwave_joint::one_line(&e),
        "bench.csv: no column `accel` (channels.accel_torque); columns: time, torsion, accel_torque"
    );

    let mut src = rows();
    src.rows[7][0] = src.rows[6][0];
    let e = run(Method::Complementary, &mut src, None).unwrap_err();
    let line = strainwave_joint::one_line(&e);
    assert!(line.starts_with("bench.csv: row 8, column `time`: time"), "{line}");

    let mut src = rows();
    let e = run(Method::OnlineCorrected, &mut src, None).unwrap_err();
    let line = strainwave_joint::one_line(&e);
    assert!(line.ends_with("bench.toml: the `online-corrected` method needs a `[model]` section"), "{line}");
}

#[test]
fn the_bench_config_spells_keys_as_the_other_configs_and_reads_the_older_ones() {
    let dir = std::env::temp_dir().join(format!("strainwave-bench-{}-spelling", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bench.toml");
    let load = |text: &str| {
        std::fs::write(&path, text).unwrap();
        BenchConfig::load(&path).map_err(|e| e.to_string())
    };
    let new = "stator_inertia_kg_m2 = 1.0e-3\nradius_m = 0.5\ncrossover_hz = 100.0\ncrossover_order = 1\n\n\
               [channels]\ntorsion = \"torsion\"\naccel_torque = \"accel\"\n";
    let c = load(new).unwrap();
    assert_eq!((c.crossover_order, c.channels.torsion.as_str()), (1, "torsion"));
    let old = load(&new.replace("crossover_order", "order").replace("[channels]", "[columns]")).unwrap();
    assert_eq!((old.crossover_order, old.channels.accel_torque), (1, Some("accel".to_string())));
    let e = load(&new.replace("crossover_order = 1", "crossover_order = 3")).unwrap_err();
    assert!(e.ends_with("bench.toml: `crossover_order` must be 1 or 2, got 3"), "{e}");
    assert_eq!(
        "hoka".parse::<Method>().unwrap_err(),
        "`hoka` is not one of online-corrected, complementary, spectral, corrected"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
