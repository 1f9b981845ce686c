//! `strainwave`: torque sensing for strain wave gear joints and motor test benches.
//!
//! A thin binary over the library crates: parse arguments, run one command, print
//! errors once. Exit codes: 0 success, 1 user error (bad file, bad value), 2 bad usage,
//! 130 / 143 / 129 interrupted (SIGINT / SIGTERM / SIGHUP), 141 output pipe closed.

#[macro_use]
mod stderr;

mod cmd_calibrate;
mod cmd_campbell;
mod cmd_convert;
mod cmd_demo;
mod cmd_design;
mod cmd_estimate;
mod cmd_export_c;
mod cmd_filter;
mod cmd_fuse;
mod cmd_identify;
mod cmd_orders;
mod cmd_report;
mod cmd_simulate;
mod cmd_spectrogram;
mod progress;
mod recording_args;
mod report;
mod signals;
mod stdout;

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use strainwave_joint::one_line;

/// Torque sensing for strain wave gear (harmonic drive) joints and motor test benches.
#[derive(Parser, Debug)]
#[command(name = "strainwave", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    #[command(flatten)]
    read: recording_args::ReadArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Fit a sensor calibration (gain, static, dynamic, speed table) and print the report.
    #[command(
        after_help = "Examples:\n  strainwave simulate --preset taghirad --procedure locked-wg --out locked.csv\n  strainwave calibrate --in locked.csv --experiment-column experiment --reference reference_torque --sensor bridge_voltage --model gain --out calibration.toml"
    )]
    Calibrate(cmd_calibrate::Args),
    /// Convert recordings between text, Parquet, MCAP and ROS 2 bags (in), streaming.
    #[command(
        after_help = "Examples:\n  strainwave convert --in log.csv --out log.parquet\n  strainwave convert --in robot.mcap --topic /dynamic_joint_states --out run.csv\n  strainwave convert --in rosbag2_folder --align hold --resample-hz 500 --out run.parquet\n  strainwave convert --in daq_export.txt --out run.csv   # tab or semicolon, decimal comma\n  strainwave convert --in jittery.csv --out uniform.csv --resample-hz 1000"
    )]
    Convert(cmd_convert::Args),
    /// Cancel torque ripple and misalignment in a recording (real time, no added delay).
    #[command(
        after_help = "Examples:\n  strainwave simulate --preset taghirad --out taghirad.csv\n  strainwave filter --config examples/joint-taghirad.toml --in taghirad.csv --out filtered.csv\n  strainwave filter --config joint.toml --in commissioning.csv --out c.csv --learn learned.toml   # then set filter.learned\n  strainwave filter --config examples/joint-taghirad.toml --in taghirad.csv --out smoothed.csv --smooth\n  cat log.csv | strainwave filter --config joint.toml --in - --out - > filtered.csv"
    )]
    Filter(cmd_filter::Args),
    /// Link torque from a motor encoder and a link encoder (the HDA-arm paper).
    #[command(
        after_help = "Example:\n  strainwave simulate --preset hda-arm --out arm.csv\n  strainwave estimate --config arm-model.toml --in arm.csv --out estimated.csv"
    )]
    Estimate(cmd_estimate::Args),
    /// Write a joint's canceller as a C initializer for the C ABI (firmware, ros2_control).
    #[command(
        after_help = "Example:\n  strainwave export-c --config examples/joint-taghirad.toml --out joint_model.h\n  strainwave export-c --config joint.toml --learned learned.toml --name JOINT3 --precision f32 --out joint3.h"
    )]
    ExportC(cmd_export_c::Args),
    /// Identify the kinematic error and the compliance of a gear from recorded runs.
    #[command(
        after_help = "Example:\n  strainwave identify --config examples/arm-hda.toml --no-load noload.csv --loaded loaded.csv --out arm-model.toml"
    )]
    Identify(cmd_identify::Args),
    /// Hybrid torque on a motor test bench: torsion shaft + accelerometers.
    #[command(
        after_help = "Example:\n  strainwave simulate --preset kit-bench --out bench.csv\n  strainwave fuse --config examples/bench-kit.toml --in bench.csv --out fused.csv"
    )]
    Fuse(cmd_fuse::Args),
    /// Campbell diagram (frequency vs speed) as SVG.
    #[command(
        after_help = "Example:\n  strainwave campbell --in bench.csv --signal accel_torque --speed speed_rpm --out campbell.svg"
    )]
    Campbell(cmd_campbell::Args),
    /// Spectrogram (frequency vs time) as SVG.
    #[command(
        after_help = "Example:\n  strainwave spectrogram --in sweep.csv --signal torsion_torque --out spectrogram.svg"
    )]
    Spectrogram(cmd_spectrogram::Args),
    /// Order slices: amplitude and phase of orders vs speed (table and SVG).
    #[command(
        after_help = "Example:\n  strainwave orders --in bench.csv --signal accel_torque --speed speed_rpm --order 18 --order 36 --out orders.svg   # the kit-bench twin's 6th and 12th electrical orders (3 pole pairs)"
    )]
    Orders(cmd_orders::Args),
    /// Simulate the Taghirad joint and print the summary; write DIR/report.html.
    #[command(after_help = "Example:\n  strainwave demo --out demo-out\n  (then open demo-out/report.html)")]
    Demo(cmd_demo::Args),
    /// Bridge sensitivity, full scale, resolution and the gauge-placement Monte Carlo.
    #[command(
        after_help = "Example:\n  strainwave design --config examples/sensor-taghirad.toml --svg residual-2x.svg"
    )]
    Design(cmd_design::Args),
    /// A self-contained HTML report of a recording (inline SVG, no scripts).
    #[command(
        after_help = "Example:\n  strainwave filter --config examples/joint-taghirad.toml --in taghirad.csv --out filtered.csv\n  strainwave report --in filtered.csv --config examples/joint-taghirad.toml --out report.html"
    )]
    Report(cmd_report::Args),
    /// Print a shell completion script.
    #[command(
        after_help = "Example:\n  strainwave completions bash > ~/.local/share/bash-completion/completions/strainwave"
    )]
    Completions {
        /// bash, zsh, fish, elvish or powershell.
        shell: clap_complete::Shell,
    },
    /// Run the joint digital twin and write a recording with `true_*` columns.
    #[command(
        after_help = "Examples:\n  strainwave simulate --preset taghirad --out taghirad.csv\n  strainwave simulate --preset taghirad --print-scenario > my-joint.toml\n  strainwave simulate --scenario my-joint.toml --duration 60 --seed 7 --out run.csv"
    )]
    Simulate(cmd_simulate::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    signals::install();
    // A panic inside a format reader is reported as an error naming the file: no trace.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !strainwave_io::guard::is_active() {
            default_hook(info);
        }
    }));
    match cli.read.options() {
        Ok(mut options) => {
            // `convert --time-column` names the clock of `--resample-hz` too.
            if let Command::Convert(a) = &cli.command {
                options.time_column = Some(a.time_column.clone());
            }
            // `--lenient` goes on over a text cell too, as a missing value.
            options.unreadable_as_nan = match &cli.command {
                Command::Filter(a) => a.lenient,
                Command::Identify(a) => a.lenient,
                _ => false,
            };
            strainwave_io::set_default_read_options(options);
        }
        Err(e) => {
            note!("error: {}", one_line(&e));
            return ExitCode::from(2);
        }
    }
    let result = match cli.command {
        Command::Calibrate(a) => cmd_calibrate::run(&a),
        Command::Convert(a) => cmd_convert::run(&a),
        Command::Demo(a) => cmd_demo::run(&a),
        Command::Design(a) => cmd_design::run(&a),
        Command::Estimate(a) => cmd_estimate::run(&a),
        Command::ExportC(a) => cmd_export_c::run(&a),
        Command::Identify(a) => cmd_identify::run(&a),
        Command::Fuse(a) => cmd_fuse::run(&a),
        Command::Campbell(a) => cmd_campbell::run(&a),
        Command::Spectrogram(a) => cmd_spectrogram::run(&a),
        Command::Orders(a) => cmd_orders::run(&a),
        Command::Filter(a) => cmd_filter::run(&a),
        Command::Simulate(a) => cmd_simulate::run(&a),
        Command::Report(a) => cmd_report::run(&a),
        Command::Completions { shell } => {
            use clap::CommandFactory;
            let mut buf = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "strainwave", &mut buf);
            stdout::print(&String::from_utf8_lossy(&buf))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if signals::is_broken_pipe(&e) => ExitCode::from(signals::BROKEN_PIPE_EXIT),
        Err(e) => {
            // A path or cell with a line break in it is shown escaped: one line.
            let line: String = one_line(&e)
                .chars()
                .flat_map(|c| if c.is_control() { c.escape_default().collect() } else { vec![c] })
                .collect();
            note!("error: {line}");
            ExitCode::from(1)
        }
    }
}
