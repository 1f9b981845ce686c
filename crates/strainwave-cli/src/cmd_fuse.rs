//! `strainwave fuse`: hybrid torque from a torsion shaft and two accelerometers.
//!
//! `online-corrected` (the default) and `complementary` stream one sample at a time
//! (constant memory): the first corrects each path with the inverse of its bench model
//! inside a fourth-order complementary pair, the second is the plain HOKA filter.
//! `spectral` (the paper's post-processing) and `corrected` (each path corrected by an
//! FIR inverse of its modelled response) read the whole recording. The job is
//! `strainwave_bench::fuse`; this module maps the flags onto it.

use std::path::{Path, PathBuf};

use anyhow::Result;
use strainwave_bench::{BenchConfig, Fuse, Method, METHODS};
use strainwave_io::{RecordingReader, RecordingWriter};

/// Arguments of `fuse`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Bench configuration (TOML; see examples/bench-kit.toml).
    #[arg(long)]
    pub config: PathBuf,
    /// Input recording.
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording: the input columns plus `fused_torque`.
    #[arg(long)]
    pub out: PathBuf,
    /// online-corrected (streamed, each path corrected by its bench model; needs
    /// `[model]`), complementary (streamed, the plain HOKA filter), spectral (the paper's
    /// offline combination) or corrected (offline, FIR-corrected paths; needs `[model]`).
    #[arg(long, default_value = "online-corrected", value_parser = method_parser())]
    pub method: Method,
    /// A reference torque column (e.g. the twin's `true_dut_torque`): prints the fused
    /// torque's worst gain and phase error against it (H1, first 2²¹ rows) over
    /// 1 Hz–2 kHz and 1 Hz–4 kHz, after its best constant delay of at most 1 ms.
    #[arg(long)]
    pub reference: Option<String>,
}

/// `--method`: the bench crate's names (its `FromStr`), listed in `--help` and in the
/// error for any other value.
fn method_parser() -> impl clap::builder::TypedValueParser<Value = Method> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(METHODS).map(|m| m.parse::<Method>().expect("one of METHODS"))
}

/// Runs `fuse`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.input.as_path(), a.config.as_path()])?;
    let cfg = BenchConfig::load(&a.config)?;
    let time = strainwave_io::Channel::column(&cfg.channels.time);
    let fuse = Fuse::new(cfg, &a.config, a.method)?;
    let mut rdr = RecordingReader::open(&a.input)?;
    rdr.set_time_channel(&time);
    // What `fuse` says goes to standard output, or to standard error when the recording does.
    let mut say = |text: &str| -> Result<()> {
        if a.out == Path::new("-") {
            crate::stderr::write(format_args!("{text}"));
            Ok(())
        } else {
            crate::stdout::print(text)
        }
    };
    let input = a.input.display().to_string();
    fuse.run(&mut rdr, |names| Ok(RecordingWriter::create(&a.out, names)?), &input, a.reference.as_deref(), &mut say)?;
    Ok(())
}
