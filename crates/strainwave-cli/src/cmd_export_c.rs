//! `strainwave export-c`: a joint config's canceller (calibration, orders, tuning, learned
//! coefficients) as a C initializer for the C ABI, to compile into drive firmware.

use std::path::PathBuf;

use anyhow::{Context, Result};
use strainwave_joint::export_c::{export_c, Precision};
use strainwave_joint::JointConfig;

/// Arguments of `export-c`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Joint configuration (TOML), as for `filter`.
    #[arg(long)]
    pub config: PathBuf,
    /// Learned coefficients (from `filter --learn`); default: the config's `filter.learned`.
    #[arg(long)]
    pub learned: Option<PathBuf>,
    /// Output C header, or `-` for standard output.
    #[arg(long)]
    pub out: PathBuf,
    /// Name of the `static const` model (a C identifier); the channels get `NAME_CHANNELS`.
    #[arg(long, default_value = "SW_MODEL")]
    pub name: String,
    /// `f64` writes an `sw_model` (the command line's numbers), `f32` an `sw32_model`.
    #[arg(long, value_enum, default_value = "f64")]
    pub precision: PrecisionArg,
}

/// `--precision`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrecisionArg {
    /// Double precision: an `sw_model`.
    F64,
    /// Single precision: an `sw32_model`.
    F32,
}

impl From<PrecisionArg> for Precision {
    fn from(p: PrecisionArg) -> Self {
        match p {
            PrecisionArg::F64 => Precision::F64,
            PrecisionArg::F32 => Precision::F32,
        }
    }
}

/// Runs `export-c`.
pub fn run(a: &Args) -> Result<()> {
    let refuse = |inputs: &[Option<&std::path::Path>]| {
        strainwave_io::output::refuse_input_as_output(&a.out, inputs.iter().copied().flatten())
    };
    refuse(&[Some(&a.config), a.learned.as_deref()])?;
    let cfg = JointConfig::load(&a.config)?;
    refuse(&[cfg.filter.learned.as_deref(), cfg.calibration.as_ref().and_then(|c| c.file.as_deref())])?;
    let text = export_c(&cfg, a.learned.as_deref(), &a.name, a.precision.into())?;
    if strainwave_io::output::is_stdout(&a.out) {
        crate::stdout::print(&text)?;
    } else {
        // A temporary file renamed into place, as every output.
        strainwave_io::output::write_file(&a.out, text).context("--out")?;
        let precision = if a.precision == PrecisionArg::F32 { "f32" } else { "f64" };
        note!("wrote {} ({precision} model of {})", a.out.display(), a.config.display());
    }
    Ok(())
}
