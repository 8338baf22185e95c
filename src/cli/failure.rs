//! Why a command stopped, and the exit code the documentation gives it: 2 for
//! input the command cannot use (a bad manifest, option or file), 1 for a run
//! that failed (an output not written, a result that disagrees).

use std::error::Error;

/// A command's failure: what the console prints after `error:`, and its class.
#[derive(Debug)]
pub enum Failure {
    /// Exit code 2: the input cannot be used.
    BadInput(Box<dyn Error>),
    /// Exit code 1: the run failed.
    Failed(Box<dyn Error>),
}

impl Failure {
    pub fn bad_input(e: impl Into<Box<dyn Error>>) -> Failure {
        Failure::BadInput(e.into())
    }

    pub fn failed(e: impl Into<Box<dyn Error>>) -> Failure {
        Failure::Failed(e.into())
    }

    /// The documented exit code.
    pub fn exit_code(&self) -> u8 {
        match self {
            Failure::BadInput(_) => 2,
            Failure::Failed(_) => 1,
        }
    }
}

/// An output that may not be claimed is bad input (2); a lock held by
/// another process or a folder that cannot be written is a failed run (1).
impl From<crate::io::output::OutputRefusal> for Failure {
    fn from(e: crate::io::output::OutputRefusal) -> Failure {
        match e {
            crate::io::output::OutputRefusal::Refused { .. } => Failure::bad_input(e),
            _ => Failure::failed(e),
        }
    }
}

/// Prints a command's failure and gives its exit code (0 on success).
pub fn exit_code(result: Result<(), Failure>) -> u8 {
    match result {
        Ok(()) => 0,
        Err(failure) => {
            let (Failure::BadInput(e) | Failure::Failed(e)) = &failure;
            eprintln!("error: {e}");
            failure.exit_code()
        }
    }
}

/// A command-line value its option does not take (clap shows it with the option).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValueError {
    #[error("--square-mm must be a positive number up to {most}, got `{text}`")]
    SquareMm { text: String, most: f64 },
    #[error("`{0}` is not a number of seconds above 0 and at most 86400 (a day)")]
    IdleSeconds(String),
    #[error("`{0}` is not HOST:PORT with a port from 1 to 65535 (e.g. localhost:18944)")]
    Address(String),
    #[error("not a number of seconds: {0}")]
    NotSeconds(String),
    #[error("{0} s: a tracker lag is between -1 and 1 s")]
    Lag(f64),
    #[error("`{0}`: a size in mm from 0.05 to 20")]
    VoxelMm(String),
    #[error("`{0}`: a lag range in ms from 10 to 200")]
    LagRangeMs(String),
}
